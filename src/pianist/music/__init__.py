"""Songs for the piano task: notes, MIDI/PIG/score files, transforms, goal frames, built-in
songs.

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
from pianist.music.fingering import (
    assign_fingering,
    assign_hands,
    ensure_fingering,
    strip_fingering,
)
from pianist.music.frames import GoalFrames, goal_frames, num_goal_frames
from pianist.music.library import SUITES, get_song, list_songs, load_song, song_description
from pianist.music.midi import read_midi, write_midi
from pianist.music.musicxml import MUSICXML_SUFFIXES, SCORE_SUFFIXES, read_musicxml, read_score
from pianist.music.notes import Note, Song
from pianist.music.open_library import OPEN_SUITE, open_song_info
from pianist.music.parts import describe_midi_hands, midi_hand_hints
from pianist.music.pig import read_pig, write_pig
from pianist.music.pig_dataset import PigDatasetError, import_pig, user_data_dir
from pianist.music.pitch import name_to_pitch, pitch_to_name
from pianist.music.playability import check_playability
from pianist.music.stats import SongStats, song_stats

__all__ = [
    "MUSICXML_SUFFIXES",
    "SCORE_SUFFIXES",
    "OPEN_SUITE",
    "SUITES",
    "GoalFrames",
    "MidiFileError",
    "MusicError",
    "Note",
    "OutOfRangeError",
    "PigDatasetError",
    "PigFormatError",
    "Song",
    "SongStats",
    "UnknownSongError",
    "assign_fingering",
    "assign_hands",
    "check_playability",
    "describe_midi_hands",
    "ensure_fingering",
    "errors",
    "get_song",
    "goal_frames",
    "import_pig",
    "list_songs",
    "load_song",
    "midi_hand_hints",
    "name_to_pitch",
    "num_goal_frames",
    "open_song_info",
    "pitch_to_name",
    "read_midi",
    "read_musicxml",
    "read_score",
    "read_pig",
    "song_description",
    "song_stats",
    "strip_fingering",
    "transforms",
    "user_data_dir",
    "write_midi",
    "write_pig",
]
