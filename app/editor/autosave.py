"""Autosave and recovery: unsaved changes are written every few seconds and offered back at the next start."""

from __future__ import annotations

import time

from app.editor import state
from app.editor.document import Document
from app.editor.editor_parts import Editor
from renderer.errors import InputError

AUTOSAVE_SECONDS = 5.0


class Autosave:
    """Keeps the recovery file of `app`'s document in `slot` (state.RECOVERY, or state.HEADLESS_RECOVERY for scripts)."""

    def __init__(self, app: Editor, slot: str) -> None:
        self.app = app
        self.slot = slot
        self.keep_on_close = True  # False once the user saved or discarded the changes on closing
        self._revision = app.doc.revision
        self._time = time.monotonic()

    def offer_recovery(self) -> None:
        """Ask whether to restore what an earlier run autosaved, if anything."""
        recovery = state.read_recovery(self.slot)
        if recovery is None:
            return
        origin = recovery.origin.name if recovery.origin else "an unsaved scene"
        text = f"Unsaved changes to {origin} were autosaved {state.age_text(recovery.saved_at)}."

        def choose(choice: str) -> None:
            if choice == "Restore":
                self.app.replace_document(Document(recovery.scene, None, changed=True))
                self.app.doc.path = recovery.origin
                self.app.say(f"restored the autosaved changes to {origin}")
            else:
                state.clear_recovery(self.slot)

        self.app.ask("Restore unsaved changes?", text, ("Restore", "Discard"), choose)

    def reset(self) -> None:
        """A new document: nothing of it to save yet."""
        self._revision = self.app.doc.revision

    def tick(self) -> None:
        """Once per frame: write the recovery file when the document changed and enough time passed."""
        if self.app.doc.revision != self._revision and time.monotonic() - self._time >= AUTOSAVE_SECONDS:
            self.now()

    def now(self) -> None:
        """Write the recovery file now if there are unsaved changes (else remove it)."""
        doc = self.app.doc
        try:
            if doc.dirty:
                state.write_recovery(doc.history.current, doc.path, self.slot)
            else:
                state.clear_recovery(self.slot)
        except (InputError, OSError) as exc:
            self.app.say(f"autosave failed: {exc}", error=True)
        self._revision = doc.revision
        self._time = time.monotonic()

    def forget(self) -> None:
        """The changes were saved or discarded: no recovery file."""
        state.clear_recovery(self.slot)

    def close(self) -> None:
        """On quitting: keep an autosave of unsaved changes unless the user chose to discard them."""
        if self.keep_on_close:
            self.now()
        else:
            self.forget()
