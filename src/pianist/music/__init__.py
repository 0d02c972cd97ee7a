"""Songs for the piano task: notes, MIDI/PIG files, transforms, goal frames, built-in songs.

This subpackage imports nothing else of :mod:`pianist`.
"""

from pianist.music import errors, transforms
from pianist.music.errors import (
    MidiFileError,
    MusicError,
    OutOfRangeError,
    PigFormatError,
    UnknownSongError,
)
from pianist.music.frames import GoalFrames, goal_frames, num_goal_frames
from pianist.music.library import get_song, list_songs, load_song, song_description
from pianist.music.midi import read_midi, write_midi
from pianist.music.notes import Note, Song
from pianist.music.pig import read_pig, write_pig
from pianist.music.pitch import name_to_pitch, pitch_to_name

__all__ = [
    "GoalFrames",
    "MidiFileError",
    "MusicError",
    "Note",
    "OutOfRangeError",
    "PigFormatError",
    "Song",
    "UnknownSongError",
    "errors",
    "get_song",
    "goal_frames",
    "list_songs",
    "load_song",
    "name_to_pitch",
    "num_goal_frames",
    "pitch_to_name",
    "read_midi",
    "read_pig",
    "song_description",
    "transforms",
    "write_midi",
    "write_pig",
]
