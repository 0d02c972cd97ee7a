"""Which hand a MIDI file's tracks or channels stand for, when the file says so.

:func:`pianist.music.midi.read_midi` merges every track and channel on one timeline (the
piano has one key per pitch). Many piano files, though, keep the hands apart: one track (or
channel) per hand, often named "Right Hand"/"Piano RH"/"Treble". :func:`midi_hand_hints`
reads that layout again and returns one hand hint per note of the song read from the file,
for :func:`pianist.music.fingering.assign_hands`.

Rules, in order:

1. Group note-ons by track when two or more tracks hold notes, else by channel.
2. A group whose track name (or instrument name) says right/left is that hand: the words
   ``right``, ``rh``, ``r.h.``, ``treble``, ``upper`` / ``left``, ``lh``, ``l.h.``, ``bass``,
   ``lower`` (and French, German, Spanish, Italian ones), in any case and also run together
   or joined by ``_``/``-`` ("Right Hand", "RightHand", "Piano_RH", "PianoLH", "Treble").
   When exactly two groups hold notes and one is named, the other is the other hand.
3. Otherwise exactly two groups whose average pitches differ by at least
   :data:`MIN_PITCH_GAP` semitones are the right (higher) and left (lower) hand.
4. Anything else (one group, three or more unnamed groups) gives no hints.
"""

from __future__ import annotations

import os
import re
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

from pianist.music.midi import PERCUSSION_CHANNEL, _load
from pianist.music.notes import LEFT, RIGHT, Song

#: Smallest difference of average pitch (semitones) for two unnamed parts to count as hands.
MIN_PITCH_GAP = 3.0
# Matched against the name cut into lower-case words (see _words): "R.H." -> "r h".
_RIGHT_WORDS = re.compile(r"\b(right|rh|r h|treble|upper|droite|rechts?|rechte|derecha|destra)\b")
_LEFT_WORDS = re.compile(r"\b(left|lh|l h|bass|lower|gauche|links?|linke|izquierda|sinistra)\b")
_DEFAULT_TEMPO_US = 500_000
# Onsets are matched to the song's notes after rounding to this many decimals of a second.
_MATCH_DIGITS = 4


def _words(name: str) -> str:
    """``name`` as lower-case words: "PianoRH" -> "piano rh", "Right_Hand" -> "right hand"."""
    name = re.sub(r"([a-z0-9])([A-Z])", r"\1 \2", name)  # camelCase / PianoRH
    name = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1 \2", name)  # RHPiano
    return " ".join(re.split(r"[^a-z]+", name.lower())).strip()


def _hand_of_name(name: str) -> str | None:
    """The hand a track or instrument name stands for, or None (neither, or both)."""
    words = _words(name)
    right, left = bool(_RIGHT_WORDS.search(words)), bool(_LEFT_WORDS.search(words))
    if right != left:
        return RIGHT if right else LEFT
    return None


def _note_ons(path: Path) -> tuple[list[tuple[int, float, int, int]], dict[int, list[str]]]:
    """(pitch, onset s, track, channel) of every note-on, and each track's names (its
    track_name, then any instrument_name)."""
    midi = _load(path)
    tpb = midi.ticks_per_beat
    # Tempo changes may sit on any track and apply to all: collect them first.
    tempos: list[tuple[int, int]] = []
    names: dict[int, list[str]] = {}
    events: list[tuple[int, int, int, int]] = []  # tick, pitch, track, channel
    for track_index, track in enumerate(midi.tracks):
        tick = 0
        track_names: list[str] = []
        instrument_names: list[str] = []
        for msg in track:
            tick += msg.time
            if msg.type == "set_tempo":
                tempos.append((tick, msg.tempo))
            elif msg.type in ("track_name", "instrument_name") and msg.name.strip():
                kind = track_names if msg.type == "track_name" else instrument_names
                kind.append(msg.name.strip())
            elif msg.type == "note_on" and msg.velocity > 0 and msg.channel != PERCUSSION_CHANNEL:
                events.append((tick, msg.note, track_index, msg.channel))  # drums: not notes
        names[track_index] = track_names + instrument_names
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


@dataclass(frozen=True)
class _Parts:
    """The file's note-ons grouped by track or channel, and the hand of each group that has one."""

    ons: list[tuple[int, float, int]]  # pitch, onset s, group
    hand_of: dict[int, str]
    labels: dict[int, str]  # group -> "'Right Hand'" (its name), "track 2" or "channel 1"
    by_name: bool  # hands from names (else from register)


def _parts(path: Path) -> _Parts | None:
    """The module rules applied to the file at ``path``; None when they give no hands."""
    ons, names = _note_ons(path)
    by_track = len({track for _, _, track, _ in ons}) >= 2
    grouped = [
        (pitch, onset, track if by_track else channel) for pitch, onset, track, channel in ons
    ]
    groups: dict[int, list[int]] = defaultdict(list)
    for pitch, _, group in grouped:
        groups[group].append(pitch)
    if len(groups) < 2:
        return None
    if by_track:
        labels = {g: repr(names[g][0]) if names.get(g) else f"track {g}" for g in groups}
    else:
        labels = {g: f"channel {g + 1}" for g in groups}
    hand_of: dict[int, str] = {}
    if by_track:
        for group in groups:
            hand = next(filter(None, map(_hand_of_name, names.get(group, []))), None)
            if hand is not None:
                hand_of[group] = hand
        if len(groups) == 2 and len(hand_of) == 1:  # "Piano RH" and "Piano": the other hand
            (hand,) = hand_of.values()
            (other,) = set(groups) - set(hand_of)
            hand_of[other] = LEFT if hand == RIGHT else RIGHT
    if hand_of:
        return _Parts(grouped, hand_of, labels, by_name=True)
    if len(groups) != 2:
        return None
    mean = {g: sum(groups[g]) / len(groups[g]) for g in groups}
    low, high = sorted(groups, key=mean.__getitem__)
    if mean[high] - mean[low] < MIN_PITCH_GAP:
        return None
    return _Parts(grouped, {low: LEFT, high: RIGHT}, labels, by_name=False)


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
    parts = _parts(Path(path))
    if parts is None:
        return None
    lookup: dict[tuple[int, float], str] = {}
    for pitch, onset, group in parts.ons:
        hand = parts.hand_of.get(group)
        if hand is not None:
            lookup.setdefault((pitch, round(onset, _MATCH_DIGITS)), hand)
    return tuple(lookup.get((n.pitch, round(n.onset_s, _MATCH_DIGITS))) for n in song.notes)


def describe_midi_hands(path: str | os.PathLike[str]) -> str | None:
    """Which of the file's parts are which hand, in words (for ``pianist info``), or None.

    E.g. "by track name: 'Right Hand' right, 'Left Hand' left" or "by register: track 1
    right, track 2 left".

    Raises:
        MidiFileError: the file cannot be read (as :func:`read_midi`).
    """
    parts = _parts(Path(path))
    if parts is None:
        return None
    named = ", ".join(f"{parts.labels[g]} {hand}" for g, hand in sorted(parts.hand_of.items()))
    return f"{'by track name' if parts.by_name else 'by register'}: {named}"
