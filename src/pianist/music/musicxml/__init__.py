"""Read scores as :class:`~pianist.music.notes.Song`: MusicXML (``.musicxml``, ``.mxl``,
``.xml``), Humdrum ``**kern`` (``.krn``), ABC (``.abc``) and MEI (``.mei``).

music21 parses the score (``pip install 'pianist[musicxml]'``); it is imported only when a
score is read. Reading conventions (a caller should know these):

- Every part's notes and chords are read, at the pitch they sound (a transposing
  instrument's part, a clarinet in B-flat, is written as its player reads it); tied notes
  are joined, voice by voice and pitch by pitch (in a chord only its tied pitches go on; a
  tie does not bridge a rest). Chord symbols (a lead sheet's "Am7") are not notes and are
  not played.
- Ornaments are played as a performer plays them (:mod:`pianist.music.ornaments`; an ABC
  tune's decorations and an MEI score's control events, which music21 does not read, are
  read first: :mod:`pianist.music.musicxml.abc`, :mod:`pianist.music.musicxml.mei`): grace
  notes on the beat, trills, mordents, turns and tremolos (on chords too), none
  of their notes shorter than two of the goal's frames where the written note leaves room;
  rolled chords one frame per note. A chord's trill, mordent or turn keeps its written
  notes; ``ornaments=False`` reads every note as written (grace notes left out).
- Repeats are played as a performer plays them (:mod:`pianist.music.repeats`: repeat signs,
  numbered endings, da capo and dal segno, al fine and al coda; an end-repeat sign without a
  start goes back to just after the previous repeat; an ending bracket without a number is
  the next ending of its run). Marks that give no order (a dal segno without a segno, a
  measure played more than :data:`~pianist.music.repeats.MAX_PLAYINGS` times, parts of
  different numbers of measures) are played once as written, with a warning. Every part
  starts each measure together. A Humdrum score's sections are played in the order its
  expansion list gives (``*>[A,A,B,A]``: :mod:`pianist.music.musicxml.humdrum`).
- Times come from the score's metronome marks (quarter = 120 before the first one, music21's
  default; a mark without a number keeps the tempo before it), and from words that name a
  tempo where no mark does at their time ("Allegro": music21's value for it, quarter = 132).
  A fermata holds its note or rest twice as long (at most 2 s longer), every part waiting.
- Velocities come from the note's own (where the file gives one), else from the part's
  dynamics marks (p, mf, ff: music21's loudness of each, times 127; sf, fz accent their
  note; a hairpin goes from one level to the next; the two staves of a grand staff share
  their marks), else 80.
- Articulation marks shape their notes (music21's shifts: staccato 0.7 of the written
  length, accent +13 velocity).
- Sustain-pedal marks are the song's pedal intervals, each from the onset of the first note
  under the mark to the end of the last; a pedal change inside a mark (``<pedal
  type="change">``) lifts the pedal for :data:`PEDAL_CHANGE_S` there.
- The piano has one key per pitch: a unison between voices or staves is one note (the longest),
  and a note struck while its key still sounds ends the earlier one.
- Hands: a score of exactly two parts (a piano's grand staff, or any two staves) gives the upper
  staff to the right hand and the lower to the left; in a larger score with one grand staff
  (a song's voice above its piano part), that staff's two halves do, and the other parts'
  notes get theirs estimated. Other scores give no hands (they are estimated, as for a MIDI
  file).
- Fingering: the score's finger numbers (1-5, the first of a substitution such as "4-3") are
  kept on the notes whose hand is known; a chord's numbers go to its notes in order when there
  is one per note. Notes without one are fingered by ``--fingering auto``.
- An ABC tune's voices play together, however the file takes turns between them (``V:``
  lines, ``[V:...]`` fields: :mod:`pianist.music.musicxml.abc`); two voices give the hands,
  the first the right (an overlay, ``&``, its voice's), or two staves of a ``%%score``
  directive do.
- A MusicXML score written measure by measure (``score-timewise``) is read as the usual
  part by part form.
- Absurd scores are refused as MIDI files are: a timeline past one hour, no notes.
"""

from pianist.music.musicxml.files import MUSICXML_SUFFIXES, SCORE_SUFFIXES, tune_reference
from pianist.music.musicxml.loudness import DEFAULT_VELOCITY, HAIRPIN_STEP
from pianist.music.musicxml.pedal import PEDAL_CHANGE_S, PedalMark
from pianist.music.musicxml.reader import (
    AS_WRITTEN,
    RawNote,
    ScoreSummary,
    merge_voices,
    read_musicxml,
    read_score,
    score_summary,
)
from pianist.music.musicxml.timing import (
    DEFAULT_QUARTER_BPM,
    FERMATA_HOLD,
    FERMATA_MAX_EXTRA_S,
    seconds_of_offsets,
)

__all__ = [
    "AS_WRITTEN",
    "DEFAULT_QUARTER_BPM",
    "DEFAULT_VELOCITY",
    "FERMATA_HOLD",
    "FERMATA_MAX_EXTRA_S",
    "HAIRPIN_STEP",
    "MUSICXML_SUFFIXES",
    "PEDAL_CHANGE_S",
    "SCORE_SUFFIXES",
    "PedalMark",
    "RawNote",
    "ScoreSummary",
    "merge_voices",
    "read_musicxml",
    "read_score",
    "score_summary",
    "seconds_of_offsets",
    "tune_reference",
]
