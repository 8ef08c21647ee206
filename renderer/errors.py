"""One exception type for bad user input, so every front end can print one line and exit 2."""

from __future__ import annotations

from pathlib import Path


class InputError(Exception):
    """Bad user input: a file that cannot be read, a value that is impossible.

    The message is a single line that names the file (when there is one) and the problem.
    """

    def __init__(self, problem: str, path: str | Path | None = None):
        self.path = None if path is None else str(path)
        self.problem = " ".join(str(problem).split())  # always one line
        super().__init__(f"{self.path}: {self.problem}" if self.path else self.problem)
