"""Checks that a fingered song can be played by two five-fingered hands.

Used to report the known kinds of broken PIG files (facts page section 4: sustain baked into
note lengths, crossed chords, wrong tempo) instead of silently training on them.
"""

from __future__ import annotations

from pianist.music.fingering import HAND_MAX_REACH_W, key_position_w
from pianist.music.notes import LEFT, RIGHT, Note, Song

#: Onsets in one second above which a file's tempo is suspect (a fast virtuoso passage
#: reaches ~20-25 notes per second with both hands).
MAX_PLAUSIBLE_NOTES_PER_SECOND = 40
_EPS_S = 1e-6


def check_playability(song: Song) -> list[str]:
    """Problems that make ``song`` unplayable as written; an empty list when none are found.

    Checks, per hand, at every onset over the keys then held down: more than five keys; one
    finger on two keys; a reach beyond an octave and a white key; fingers in the wrong order
    for the pitches (a crossed chord). And, for the song: more onsets in one second than
    :data:`MAX_PLAUSIBLE_NOTES_PER_SECOND` (a wrong tempo). Each problem is one line giving
    how often it occurs and the first time (s).
    """
    problems: list[str] = []
    for hand in (RIGHT, LEFT):
        counts: dict[str, list[float]] = {
            "crowded": [],
            "finger": [],
            "reach": [],
            "crossed": [],
        }
        sounding: list[Note] = []
        for note in (n for n in song.notes if n.hand == hand):
            sounding = [n for n in sounding if n.offset_s > note.onset_s + _EPS_S]
            sounding.append(note)
            if len(sounding) > 5:
                counts["crowded"].append(note.onset_s)
            fingered = [n for n in sounding if n.finger is not None]
            fingers = [n.finger for n in fingered]
            if len(set(fingers)) < len(fingers):
                counts["finger"].append(note.onset_s)
            positions = [key_position_w(n.pitch) for n in sounding]
            if max(positions) - min(positions) > HAND_MAX_REACH_W:
                counts["reach"].append(note.onset_s)
            by_pitch = sorted(fingered, key=lambda n: n.pitch)
            order = [n.finger for n in by_pitch if n.finger is not None]  # (all fingered)
            expected = sorted(order) if hand == RIGHT else sorted(order, reverse=True)
            if len({n.pitch for n in by_pitch}) == len(by_pitch) and order != expected:
                counts["crossed"].append(note.onset_s)
        words = {
            "crowded": "more than five keys held at once (sustain baked into note lengths?)",
            "finger": "one finger on two keys held at once",
            "reach": "keys held at once wider apart than an octave and a white key",
            "crossed": "fingers crossed within keys held at once (crossed chord)",
        }
        for kind, times in counts.items():
            if times:
                problems.append(
                    f"{hand} hand: {words[kind]}: {len(times)} time(s), first at {times[0]:.2f} s"
                )
    onsets = [n.onset_s for n in song.notes]
    start = 0
    for end, onset in enumerate(onsets):
        while onsets[start] <= onset - 1.0:
            start += 1
        if end - start + 1 > MAX_PLAUSIBLE_NOTES_PER_SECOND:
            problems.append(
                f"more than {MAX_PLAUSIBLE_NOTES_PER_SECOND} onsets within one second at "
                f"{onsets[start]:.2f} s (wrong tempo?)"
            )
            break
    return problems
