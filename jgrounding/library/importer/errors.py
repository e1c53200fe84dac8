"""The importer's error types: one problem (:class:`DemonstrationError`), every problem of a run
(:class:`ImportProblems`) and a ``--drop-invalid`` run that would leave out too much (:class:`TooManyDropped`).
Imports nothing else of the package."""

from __future__ import annotations

from pathlib import Path


class DemonstrationError(ValueError):
    """Bad input data; the message names the file, the line (1-based, as an editor shows it), the column,
    and how to fix it."""

    def __init__(
        self,
        file,
        reason: str,
        line: int | None = None,
        column: str | None = None,
        unit: str = "line",
        fix: str | None = None,
    ):
        self.file, self.line, self.column, self.reason, self.unit, self.fix = str(file), line, column, reason, unit, fix
        super().__init__(f"{self.where}: {reason}" + (f". Fix: {fix}" if fix else ""))

    @property
    def where(self) -> str:
        """``file line N, column 'c'`` (``entry N`` in a JSON manifest, ``command N`` in a command stream)."""
        return (
            self.file
            + (f" {self.unit} {self.line}" if self.line is not None else "")
            + (f", column {self.column!r}" if self.column else "")
        )

    def as_dict(self) -> dict:
        return {
            "file": self.file,
            self.unit: self.line,
            "column": self.column,
            "reason": self.reason,
            "fix": self.fix,
            "where": self.where,
        }

    def with_fix(self, more: str) -> DemonstrationError:
        """This problem with ``more`` appended to its fix (``; `` between)."""
        fix = (self.fix + "; " if self.fix else "") + more
        return DemonstrationError(self.file, self.reason, self.line, self.column, self.unit, fix=fix)


class ImportProblems(DemonstrationError):
    """Every problem of one file or one import run: ``problems`` is the list, the message has one per line
    (and, with ``files``, a summary line of the run)."""

    def __init__(self, problems: list[DemonstrationError], files: int | None = None):
        self.problems = list(problems)
        first = self.problems[0]
        super().__init__(first.file, first.reason, first.line, first.column, first.unit, first.fix)
        bad = len({p.file for p in self.problems})
        self.args = (
            "\n".join(str(p) for p in self.problems)
            + (
                f"\n{len(self.problems)} problem(s) in {bad} file(s) ({files} listed in the manifest); nothing was "
                "written (fix them, or pass --drop-invalid to import the rest)"
                if files is not None
                else ""
            ),
        )

    def __str__(self) -> str:
        return self.args[0]


def problems_of(error: DemonstrationError) -> list[DemonstrationError]:
    """The single problems inside ``error`` (itself, or the list of an :class:`ImportProblems`)."""
    return list(error.problems) if isinstance(error, ImportProblems) else [error]


def raise_if_any(problems: list[DemonstrationError]) -> None:
    """Raise every one of ``problems`` together (:class:`ImportProblems`), or nothing when there are none."""
    if problems:
        raise ImportProblems(problems)


class TooManyDropped(DemonstrationError):
    """``--drop-invalid`` past ``--max-dropped``: the problems and rejections are listed, nothing is written."""

    def __init__(self, problems: list, rejected: list, summary: str, manifest: Path):
        self.problems, self.rejected = list(problems), list(rejected)
        super().__init__(
            manifest,
            summary,
            fix="fix the files listed above, or pass a larger --max-dropped to accept the rest anyway",
        )
        self.args = (
            "\n".join(
                [str(p) for p in self.problems]
                + [f"rejected by screening: {r['file']} (failed: {', '.join(r['failed'])})" for r in self.rejected]
                + [f"{self.where}: {summary}. Fix: {self.fix}"]
            ),
        )

    def __str__(self) -> str:
        return self.args[0]
