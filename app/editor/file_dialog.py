"""The system's file dialog for the Browse buttons beside the path fields: zenity or kdialog, run as a program.

Without either program there are no Browse buttons and files are named by typing in the path
fields. The dialog runs as a separate process, so the window keeps drawing while it is open;
the interface polls it once a frame.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass

PROGRAMS = ("zenity", "kdialog")  # in order of preference


@dataclass(frozen=True)
class FileKind:
    """What a dialog asks for: its title, a name for the files and their patterns, and whether it picks a new file."""

    title: str
    name: str
    patterns: tuple[str, ...]
    save: bool = False


def dialog_program() -> str | None:
    """The first dialog program found on PATH, or None."""
    return next((program for program in PROGRAMS if shutil.which(program)), None)


def dialog_command(program: str, kind: FileKind, start: str = "") -> list[str]:
    """The command line that shows `program`'s file dialog for `kind`, starting at the file or folder `start`."""
    patterns = " ".join(kind.patterns)
    if program == "zenity":
        command = ["zenity", "--file-selection", f"--title={kind.title}"]
        if kind.save:
            command.append("--save")
        if start:
            command.append(f"--filename={start}")
        return [*command, f"--file-filter={kind.name} | {patterns}", "--file-filter=All files | *"]
    if program == "kdialog":
        mode = "--getsavefilename" if kind.save else "--getopenfilename"
        return ["kdialog", "--title", kind.title, mode, start or ".", f"{patterns}|{kind.name}"]
    raise ValueError(f"unknown dialog program {program!r} (known: {', '.join(PROGRAMS)})")


class FileDialog:
    """A dialog program running in the background. `poll` tells when it closed; `path` is then the chosen file."""

    def __init__(self, command: Sequence[str]):
        self.path: str | None = None  # None: still open, cancelled or failed
        self.error: str | None = None
        try:
            self._process: subprocess.Popen | None = subprocess.Popen(
                list(command), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        except OSError as exc:
            self._process = None
            self.error = f"cannot start the file dialog {command[0]}: {exc.strerror or exc}"

    def poll(self) -> bool:
        """True once the dialog has closed (at once if it could not start)."""
        process = self._process
        if process is None:
            return True
        if process.poll() is None:
            return False
        chosen = process.stdout.read().strip().splitlines()
        process.stdout.close()
        self._process = None
        if process.returncode == 0 and chosen:  # a cancelled dialog exits 1 and prints nothing
            self.path = chosen[0]
        return True

    def close(self) -> None:
        """Close the dialog if it is still open (the window is closing)."""
        if self._process is not None and self._process.poll() is None:
            self._process.terminate()
            self._process.wait()
        self._process = None
