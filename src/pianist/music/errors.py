"""Exceptions raised by :mod:`pianist.music`.

Every message is a single readable line that names the file or song and the problem, because
the command line prints ``str(exc)`` as is.
"""

from __future__ import annotations


class MusicError(ValueError):
    """Base class of every error about songs, MIDI or PIG files."""


class MidiFileError(MusicError):
    """A MIDI file is missing, unreadable, corrupt, empty of notes or of absurd tempo/length."""


class OutOfRangeError(MusicError):
    """Notes fall outside the 88 piano keys (MIDI 21..108)."""


class PigFormatError(MusicError):
    """A PIG fingering file (or a song to be written as one) breaks the PIG format."""


class UnknownSongError(MusicError, LookupError):
    """A song name is neither a built-in song nor a path to a file."""


def one_line(text: object) -> str:
    """Collapse ``text`` to one line so that wrapped third-party messages stay printable."""
    return " ".join(str(text).split())
