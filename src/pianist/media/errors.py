"""The one exception type of :mod:`pianist.media`."""

from __future__ import annotations


class MediaError(Exception):
    """A media file could not be made; the message is one line, fit to show to a user."""
