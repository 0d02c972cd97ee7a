"""``pianist report``: the page of one result folder, or one page comparing several."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import tyro

from pianist.cli.common import out as _out


@dataclass(frozen=True)
class Report:
    """Write report.html for result folders of `pianist play`: metrics, piano roll, audio and
    video players, missed and wrong notes, the song's provenance. Several folders give one
    page comparing them (--out required). The page references the folders' media by relative
    path and needs no network."""

    dirs: Annotated[
        tuple[Path, ...],
        tyro.conf.Positional,
        tyro.conf.arg(metavar="DIR [DIR ...]", help_behavior_hint="(one or more)"),
    ]
    """Result folders (what `pianist play --out DIR` wrote)."""
    out: Annotated[
        Path | None,
        tyro.conf.arg(
            metavar="PATH", help_behavior_hint="(default: DIR/report.html for one folder)"
        ),
    ] = None
    """The HTML file to write; required for several folders."""
    title: str = ""
    """The page's heading (default: the folder's name)."""

    def run(self) -> None:
        from pianist.media.report import write_report

        page = write_report(list(self.dirs), self.out, title=self.title)
        _out(f"report of {len(self.dirs)} run{'s' if len(self.dirs) > 1 else ''} -> {page}")
