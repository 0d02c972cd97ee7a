"""Size and difficulty figures of a song, for listings (``pianist songs``) and benchmarks."""

from __future__ import annotations

import bisect
from dataclasses import asdict, dataclass
from typing import Any

from pianist.music.notes import HANDS, Song

_EPS_S = 1e-9


@dataclass(frozen=True)
class SongStats:
    """Figures of one song; see :func:`song_stats`.

    Attributes:
        duration_s: seconds until the last note or pedal interval ends.
        num_notes: number of notes.
        notes_per_second: ``num_notes / duration_s`` (0 for an empty song).
        peak_notes_per_second: most onsets within any one-second window.
        max_polyphony: most keys sounding at the same moment.
        max_hand_span: widest interval, semitones, between keys sounding together in one hand
            (None when no note names a hand).
        fingering_coverage: fraction of notes with a finger, 0..1.
        hands: hands named by the notes, sorted ("left", "right").
    """

    duration_s: float
    num_notes: int
    notes_per_second: float
    peak_notes_per_second: int
    max_polyphony: int
    max_hand_span: int | None
    fingering_coverage: float
    hands: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        """Plain dict (JSON-ready)."""
        return asdict(self)


def _max_overlap(intervals: list[tuple[float, float]]) -> int:
    # Ends sort before starts at the same time: a key released as another is struck is not
    # two keys at once.
    events = sorted([(s, 1) for s, _ in intervals] + [(e, -1) for _, e in intervals])
    best = current = 0
    for _, step in events:
        current += step
        best = max(best, current)
    return best


def _hand_span(song: Song, hand: str) -> int | None:
    notes = [n for n in song.notes if n.hand == hand]  # sorted by onset
    if not notes:
        return None
    best = 0
    sounding: list = []
    for note in notes:
        sounding = [n for n in sounding if n.offset_s > note.onset_s + _EPS_S]
        sounding.append(note)
        pitches = [n.pitch for n in sounding]
        best = max(best, max(pitches) - min(pitches))
    return best


def song_stats(song: Song) -> SongStats:
    """Duration, note count and difficulty figures of ``song`` (see :class:`SongStats`)."""
    duration = song.duration_s
    onsets = [n.onset_s for n in song.notes]
    peak = 0
    for i, onset in enumerate(onsets):  # onsets are sorted: count those in [onset, onset + 1)
        peak = max(peak, bisect.bisect_left(onsets, onset + 1.0 - _EPS_S, lo=i) - i)
    spans = [s for s in (_hand_span(song, hand) for hand in HANDS) if s is not None]
    return SongStats(
        duration_s=duration,
        num_notes=song.num_notes,
        notes_per_second=song.num_notes / duration if duration > 0 else 0.0,
        peak_notes_per_second=peak,
        max_polyphony=_max_overlap([(n.onset_s, n.offset_s) for n in song.notes]),
        max_hand_span=max(spans) if spans else None,
        fingering_coverage=song.fingering_coverage,
        hands=tuple(sorted(song.hands)),
    )
