"""Which hand a MIDI file's tracks or channels stand for, when the file says so.

:func:`pianist.music.midi.read_midi` merges every track and channel on one timeline (the
piano has one key per pitch). Many piano files, though, keep the hands apart: one track (or
channel) per hand, often named "Right Hand"/"Piano RH"/"Treble". :func:`midi_hand_hints`
reads that layout again and returns one hand hint per note of the song read from the file,
for :func:`pianist.music.fingering.assign_hands`.

Rules, in order:

1. Group note-ons by track when two or more tracks hold notes, else by channel.
2. A group whose track name says right/left (``right``, ``rh``, ``treble``, ``upper`` /
   ``left``, ``lh``, ``bass``, ``lower``) is that hand.
3. Otherwise exactly two groups whose average pitches differ by at least
   :data:`MIN_PITCH_GAP` semitones are the right (higher) and left (lower) hand.
4. Anything else (one group, three or more unnamed groups) gives no hints.
"""

from __future__ import annotations

import os
import re
from collections import defaultdict
from pathlib import Path

from pianist.music.midi import _load
from pianist.music.notes import LEFT, RIGHT, Song

#: Smallest difference of average pitch (semitones) for two unnamed parts to count as hands.
MIN_PITCH_GAP = 3.0
_RIGHT_WORDS = re.compile(r"\b(right|rh|r\.h\.|treble|upper|droite|rechts?)\b", re.IGNORECASE)
_LEFT_WORDS = re.compile(r"\b(left|lh|l\.h\.|bass|lower|gauche|links?)\b", re.IGNORECASE)
_DEFAULT_TEMPO_US = 500_000
# Onsets are matched to the song's notes after rounding to this many decimals of a second.
_MATCH_DIGITS = 4


def _hand_of_name(name: str) -> str | None:
    right, left = bool(_RIGHT_WORDS.search(name)), bool(_LEFT_WORDS.search(name))
    if right != left:
        return RIGHT if right else LEFT
    return None


def _note_ons(path: Path) -> tuple[list[tuple[int, float, int, int]], dict[int, str]]:
    """(pitch, onset s, track, channel) of every note-on, and each track's name."""
    midi = _load(path)
    tpb = midi.ticks_per_beat
    # Tempo changes may sit on any track and apply to all: collect them first.
    tempos: list[tuple[int, int]] = []
    names: dict[int, str] = {}
    events: list[tuple[int, int, int, int]] = []  # tick, pitch, track, channel
    for track_index, track in enumerate(midi.tracks):
        tick = 0
        for msg in track:
            tick += msg.time
            if msg.type == "set_tempo":
                tempos.append((tick, msg.tempo))
            elif msg.type == "track_name" and track_index not in names:
                names[track_index] = msg.name
            elif msg.type == "note_on" and msg.velocity > 0:
                events.append((tick, msg.note, track_index, msg.channel))
    tempos.sort(key=lambda t: t[0])
    # Piecewise-linear tick -> seconds map, the same arithmetic as read_midi.
    segments = [(0, 0.0, _DEFAULT_TEMPO_US)]
    for tick, tempo in tempos:
        start_tick, start_s, current = segments[-1]
        seconds = start_s + (tick - start_tick) * current / (1_000_000 * tpb)
        segments.append((tick, seconds, tempo))
    found = []
    events.sort(key=lambda e: e[0])
    segment = 0
    for tick, pitch, track_index, channel in events:
        while segment + 1 < len(segments) and segments[segment + 1][0] <= tick:
            segment += 1
        start_tick, start_s, tempo = segments[segment]
        found.append(
            (pitch, start_s + (tick - start_tick) * tempo / (1_000_000 * tpb), track_index, channel)
        )
    return found, names


def midi_hand_hints(path: str | os.PathLike[str], song: Song) -> tuple[str | None, ...] | None:
    """One hand hint per note of ``song`` (read from ``path``), or None if the file has none.

    Args:
        path: the MIDI file ``song`` was read from (:func:`~pianist.music.midi.read_midi`).
        song: that song; its notes are matched to the file's note-ons by pitch and onset.
    Returns:
        A tuple aligned with ``song.notes`` ("left", "right" or None per note), or None when
        the file's tracks and channels do not tell the hands apart (see the module rules).

    Raises:
        MidiFileError: the file cannot be read (as :func:`read_midi`).
    """
    path = Path(path)
    ons, names = _note_ons(path)
    tracks = {track for _, _, track, _ in ons}
    by_track = len(tracks) >= 2
    groups: dict[int, list[int]] = defaultdict(list)
    for pitch, _, track, channel in ons:
        groups[track if by_track else channel].append(pitch)
    if len(groups) < 2:
        return None
    hand_of: dict[int, str] = {}
    if by_track:
        for group in groups:
            hand = _hand_of_name(names.get(group, ""))
            if hand is not None:
                hand_of[group] = hand
    if not hand_of:
        if len(groups) != 2:
            return None
        low, high = sorted(groups, key=lambda g: sum(groups[g]) / len(groups[g]))
        mean = {g: sum(groups[g]) / len(groups[g]) for g in groups}
        if mean[high] - mean[low] < MIN_PITCH_GAP:
            return None
        hand_of = {low: LEFT, high: RIGHT}
    lookup: dict[tuple[int, float], str] = {}
    for pitch, onset, track, channel in ons:
        hand = hand_of.get(track if by_track else channel)
        if hand is not None:
            lookup.setdefault((pitch, round(onset, _MATCH_DIGITS)), hand)
    return tuple(lookup.get((n.pitch, round(n.onset_s, _MATCH_DIGITS))) for n in song.notes)
