"""Subcommands about songs: list them, describe one, import the PIG dataset."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import tyro

from pianist.cli.common import SongArg
from pianist.cli.common import out as _out

if TYPE_CHECKING:
    from pianist.music.musicxml import ScoreSummary


@dataclass(frozen=True)
class Songs:
    """List songs with their size and difficulty: duration, notes, notes/s, span, polyphony."""

    suite: Literal[
        "all",
        "debug",
        "robopianist-debug",
        "octaves",
        "dynamics",
        "open-etude-12",
        "etude-12",
        "repertoire-150",
    ] = "all"
    """Which suite: the debug songs, the original's debug songs note for note, pieces at an
    octave's stretch, pieces with marked loudness, the shipped open library, or imported PIG
    pieces."""

    def run(self) -> None:
        from pianist.music import SUITES, PigDatasetError, list_songs, load_song, song_stats

        suites = SUITES if self.suite == "all" else (self.suite,)
        listed = []  # every suite's names first: a missing one fails before the table starts
        for suite in suites:
            try:
                listed.append((suite, list_songs(suite)))
            except PigDatasetError:
                if self.suite == "all":
                    continue  # PIG suites appear once `pianist import-pig` has run
                raise
        _out(
            f"{'name':40s} {'suite':17s} {'s':>6s} {'notes':>5s} {'n/s':>5s} "
            f"{'span':>4s} {'poly':>4s}"
        )
        flagged = False
        for suite, names in listed:
            for name in names:
                # Known-broken PIG pieces warn on load: a mark in the table, not a warning each.
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    stats = song_stats(load_song(name))
                flagged |= bool(caught)
                span = "-" if stats.max_hand_span is None else str(stats.max_hand_span)
                _out(
                    f"{name:40s} {suite:17s} {stats.duration_s:6.1f} {stats.num_notes:5d} "
                    f"{stats.notes_per_second:5.1f} {span:>4s} {stats.max_polyphony:4d}"
                    + (" !" if caught else "")
                )
        _out(
            "s: duration in seconds; n/s: notes per second; span: widest hand span in "
            "semitones (keys held together in one hand; - without hands); poly: most notes "
            "sounding at once"
            + ("; !: known problems (`pianist info NAME` lists them)" if flagged else "")
        )


@dataclass(frozen=True)
class ImportPig:
    """Convert a copy of the PIG fingering dataset into songs (RoboPianist etude-12 and
    repertoire-150 names then resolve like built-in songs).

    Every command looks the songs up in one folder, where they are written by default:
    PIANIST_PIG if set, else pig/ in PIANIST_DATA, else ~/.local/share/pianist/pig (the XDG
    data folder). After an import with --dest elsewhere, set PIANIST_PIG to that folder (the
    import prints the exact line): a variable, not a hidden record, keeps each lookup explicit.
    """

    src: tyro.conf.Positional[Annotated[Path, tyro.conf.arg(metavar="DIR")]]
    """The dataset folder (e.g. PianoFingeringDataset_v1.2, with FingeringFiles/ and List.csv)."""
    dest: Annotated[
        Path | None,
        tyro.conf.arg(
            metavar="PATH", help_behavior_hint="(default: where songs are looked up, see above)"
        ),
    ] = None
    """Where to write the songs."""
    strict: bool = True
    """Stop at the first unreadable file (else skip it and report it)."""

    def run(self) -> None:
        from pianist.music import import_pig

        _out(import_pig(self.src, self.dest, strict=self.strict).summary())


@dataclass(frozen=True)
class Info:
    """Describe a song: duration, notes, hands, fingering coverage, goal frames.

    Hands and fingers the file lacks are given as `play` (with its default --fingering auto)
    estimates them, saying where the hands come from: the file's fingering, a MIDI file's
    tracks (named "Right Hand", "LH", "Treble", ... or told apart by register), or estimated.
    """

    song: tyro.conf.Positional[SongArg]
    """A built-in song name, a MIDI file (.mid), a PIG fingering file (.txt) or a score
    (MusicXML .musicxml, .mxl, .xml; Humdrum .krn; ABC .abc; MEI .mei: hands from its
    staves, its finger numbers; needs music21)."""
    out_of_range: Literal["error", "drop"] = "error"
    """A file's notes outside the piano's 88 keys: refuse the file (error) or describe it
    without them (drop), as `pianist play` would play it."""

    def run(self) -> None:
        from pianist.music import (
            SCORE_SUFFIXES,
            check_playability,
            describe_midi_hands,
            goal_frames,
            load_song,
            pitch_to_name,
            song_stats,
        )

        # Warnings on load (a known-broken PIG piece) are part of the description.
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            summary = _score_summary(self.song)  # a score is parsed once
            song = (
                summary.song
                if summary is not None
                else load_song(self.song, out_of_range=self.out_of_range)
            )
            # What `play` plays by default: the missing hands and fingers estimated (from
            # the file again only for MIDI, whose tracks hint at the hands).
            is_midi = Path(self.song).suffix.lower() in (".mid", ".midi")
            source = self.song if is_midi else song
            played = (
                song
                if song.has_full_fingering
                else load_song(source, fingering="auto", out_of_range=self.out_of_range)
            )
        problems = list(dict.fromkeys(" ".join(str(w.message).split()) for w in caught))
        problems += [p for p in check_playability(played) if not any(p in q for q in problems)]
        stats = song_stats(played)
        frames = goal_frames(song)
        pitches = [n.pitch for n in song.notes]
        hands = ", ".join(sorted(played.hands)) or "-"
        from_score = Path(self.song).suffix.lower() in SCORE_SUFFIXES
        if from_score and song.notes and all(n.hand is not None for n in song.notes):
            hands += " (from the score's staves)"
        elif any(n.hand is None for n in song.notes):
            parts = describe_midi_hands(self.song) if is_midi else None
            if parts is not None:
                hands += f" (from the MIDI file, {parts})"
            elif song.hands:
                where = "the score's staves" if from_score else "the file"
                hands += f" (partly estimated: {where} name a hand for some notes)"
            else:
                hands += " (estimated: the file does not tell the two hands apart)"
        fingering = f"{100 * song.fingering_coverage:.0f}% of notes"
        if not song.has_full_fingering and song.notes:
            fingering += " in the file (play estimates the rest: --fingering auto)"
        lines = [
            f"song:       {song.name or self.song}",
            f"duration:   {song.duration_s:.2f} s",
            f"notes:      {song.num_notes}",
        ]
        if pitches:
            lines.append(
                f"range:      {pitch_to_name(min(pitches))} - {pitch_to_name(max(pitches))}"
            )
        if summary is not None:  # a score: what its repeats and ornaments add
            once = summary.once_through_s
            if any("repeats could not be expanded" in problem for problem in problems):
                lines.append("repeats:    not played (see the warning)")
            elif abs(once - song.duration_s) < 1e-6:
                lines.append("repeats:    none")
            else:
                lines.append(f"repeats:    played ({once:.2f} s once through as written)")
            ornaments = ", ".join(
                f"{n} {kind if n != 1 else kind.removesuffix('s')}"
                for kind, n in summary.ornaments.items()
            )
            played_as = " (played; any quicker than a frame as written)" if ornaments else ""
            lines.append(f"ornaments:  {ornaments or 'none'}{played_as}")
        lines += [
            f"hands:      {hands}",
            f"fingering:  {fingering}",
            f"sustain:    {len(song.sustain)} pedal intervals",
            f"goal:       {frames.num_frames} frames at {1 / frames.dt:g} Hz, "
            f"max {int(frames.keys.sum(axis=1).max(initial=0))} keys at once",
            f"difficulty: {stats.notes_per_second:.1f} notes/s (peak {stats.peak_notes_per_second}"
            f" in 1 s), polyphony {stats.max_polyphony}, hand span "
            + ("-" if stats.max_hand_span is None else f"{stats.max_hand_span} semitones"),
        ]
        lines += [f"warning:    {problem}" for problem in problems]
        _out("\n".join(lines))


def _score_summary(song: str) -> ScoreSummary | None:
    """A score's song, its duration once through and its ornaments, from one parse
    (:func:`pianist.music.musicxml.score_summary`); None for anything else."""
    from pianist.music import SCORE_SUFFIXES
    from pianist.music.musicxml import score_summary, tune_reference

    is_score = Path(song).suffix.lower() in SCORE_SUFFIXES and Path(song).is_file()
    if not is_score and tune_reference(song) is None:
        return None
    return score_summary(song)
