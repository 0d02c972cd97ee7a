"""Write a song as a plain MIDI file: its notes, one track per hand named "Right Hand" and
"Left Hand", and no fingering, as a MIDI file from elsewhere would come.

What ``benchmarks/bench_practice.py`` practises to check that a piece read from a MIDI file
(fingered automatically) is learned as well as the built-in, fingered one.

Usage:
    python scripts/export_song_midi.py SONG OUT.mid
"""

from __future__ import annotations

import argparse

import pretty_midi

from pianist.music import load_song

TRACK_NAMES = {"right": "Right Hand", "left": "Left Hand"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("song", help="a built-in song name, a PIG file or a MIDI file")
    parser.add_argument("out", help="the MIDI file to write")
    args = parser.parse_args()
    song = load_song(args.song)
    midi = pretty_midi.PrettyMIDI()
    tracks = {hand: pretty_midi.Instrument(0, name=name) for hand, name in TRACK_NAMES.items()}
    for note in song.notes:
        tracks[note.hand or "right"].notes.append(
            pretty_midi.Note(
                velocity=note.velocity, pitch=note.pitch, start=note.onset_s, end=note.offset_s
            )
        )
    midi.instruments.extend(track for track in tracks.values() if track.notes)
    midi.write(args.out)


if __name__ == "__main__":
    main()
