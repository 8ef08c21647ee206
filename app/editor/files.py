"""The editor's file commands: open, new, save, exports, MagicaVoxel files, turntables and meshes.

Every write is atomic, asks before replacing a file the user did not choose to replace, and never writes over
the files that ship with NVR Studio; every failure is a message in the window and the scene stays as it was.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from app.editor import edits, side_by_side, state
from app.editor.document import Document
from app.editor.editor_parts import EditorWithViews
from app.editor.jobs import Progress
from app.editor.orbit_view import viewport_camera
from app.editor.render_panel import export_render, final_render
from renderer.color import to_uint8
from renderer.errors import InputError
from renderer.io import save_png
from renderer.limits import MAX_OBJECTS
from renderer.mesh import MESH_EXTENSIONS
from renderer.scene import ObjectSpec, Scene, save_scene

SHIPPED_ASSETS = Path(__file__).resolve().parents[2] / "assets"  # the demo scene and models: Save writes elsewhere


def shipped(path: str | Path | None) -> bool:
    """Whether `path` is one of the files that ship with NVR Studio (never saved over, nor exported beside)."""
    return path is not None and Path(path).resolve().is_relative_to(SHIPPED_ASSETS)


def new_scene() -> Scene:
    """What File > New starts from: the demo chair (by absolute path) in the default set-up, no file yet."""
    return Scene.single(object=ObjectSpec(mesh=str(SHIPPED_ASSETS / "demo" / "chair.obj"), rotation_deg=30.0))


def finer_for_export(scene: Scene, resolution: int) -> Scene:
    """The scene with its objects' meshes voxelised at `resolution` for an export; an object without a mesh, or
    painted stroke by stroke (the strokes name voxels of its own resolution), keeps its voxels. Refused (InputError)
    when no object can be voxelised more finely."""
    finer = [o.mesh is not None and not any(op.target == "region" for op in o.paint) for o in scene.objects]
    if not any(finer):
        if all(o.mesh is None for o in scene.objects):
            raise InputError("the object has no mesh to voxelise more finely: it exports at its own voxels")
        raise InputError(f"the object's paint strokes are on its {scene.objects[0].resolution}^3 voxels: it exports "
                         "at them")
    objects = tuple(replace(o, resolution=int(resolution)) if fine else o for o, fine in zip(scene.objects, finer))
    return scene.with_changes(objects=objects)  # validated as any edit


class FileCommands:
    """What the File menu and tab, the keys and the replay file ask of `app`'s document and files."""

    def __init__(self, app: EditorWithViews) -> None:
        self.app = app

    # --- documents ----------------------------------------------------------------------------

    def open_scene(self, path: str | Path) -> None:
        """Open a scene file, asking first when the current one has unsaved changes."""
        def go() -> None:
            try:
                self.app.replace_document(Document.open(path))
            except InputError as exc:
                self.app.say(str(exc), error=True)
                return
            state.remember_scene(path)
            self.app.say(f"opened {path}")

        self.replace_after_asking("Save the current scene before opening another?", go)

    def open(self, path: str | Path) -> None:
        """File > Open: a scene file opens as it is; a mesh or a MagicaVoxel model starts a new scene holding it (after
        asking about unsaved changes), and the status line says which it opened."""
        suffix = Path(path).suffix.lower()
        if suffix in (".json", ""):
            self.open_scene(path)
            return
        if suffix not in (*MESH_EXTENSIONS, ".vox"):
            self.app.say(f"{path}: Open takes scenes (.json), meshes ({', '.join(MESH_EXTENSIONS)}) and MagicaVoxel "
                         f"models (.vox), not {suffix}", error=True)
            return

        def go() -> None:
            self.app.replace_document(Document(new_scene(), None))
            kind = "MagicaVoxel model" if suffix == ".vox" else "mesh"
            self.app.say(f"new scene from the {kind} {Path(path).resolve()}")
            self.import_vox(path) if suffix == ".vox" else self.load_mesh(path)

        self.replace_after_asking("Save the current scene before opening another?", go)

    def new_scene(self) -> None:
        """Start a new, unsaved scene with the demo chair (asking first about unsaved changes)."""
        def go() -> None:
            self.app.replace_document(Document(new_scene(), None))
            self.app.say("new scene: load a mesh in the Object tab, or import a .vox")

        self.replace_after_asking("Save the current scene before starting a new one?", go)

    def replace_after_asking(self, question: str, replace_document: Callable[[], None]) -> None:
        """Run `replace_document`, first asking whether to save unsaved changes (Save, Discard or Cancel)."""
        def choose(choice: str) -> None:
            if choice == "Cancel" or (choice == "Save" and not self.save()):
                return
            replace_document()

        doc = self.app.doc
        if doc.dirty:
            choices = ("Save", "Discard", "Cancel") if doc.path else ("Discard", "Cancel")
            self.app.ask("Unsaved changes", question, choices, choose)
        else:
            replace_document()

    def save(self, path: str | Path | None = None, overwrite: bool = False) -> bool:
        """Write the scene (atomically) to `path` or to the file it came from; asks before replacing another file."""
        app, doc = self.app, self.app.doc
        target = Path(path) if path else doc.path
        if target is None:
            app.say("choose a file name to save to (File tab)", error=True)
            app.requested_tab = "File"
            return False
        if path is None and shipped(target):
            app.say(f"{target.name} ships with NVR Studio and is not saved over: choose a file name (File tab, Save as)",
                    error=True)
            app.requested_tab = "File"
            return False
        own_file = doc.path is not None and target.resolve() == doc.path.resolve() and not shipped(target)

        def write() -> str:
            doc.cancel_preview()
            save_scene(state.adopt_capture(app.scene, target), target)
            doc.mark_saved(target)
            app.autosave.forget()
            state.remember_scene(target)
            return f"saved {target.resolve()}"

        return self.write_file(target, overwrite or own_file, write)

    # --- exports ------------------------------------------------------------------------------

    def export(self, path: str | Path, overwrite: bool = False, size: int | None = None,
               voxels: int | None = None) -> bool:
        """Write the panel renderer's image of the committed scene at `size` pixels (default the scene's; a network's
        image of another size is resized and the message says so). `voxels`: voxelise the object's mesh at that
        resolution for this export alone (finer voxels for a large image; the scene keeps its own)."""
        app = self.app
        scene = app.doc.history.current
        if voxels is not None and any(voxels != o.resolution for o in scene.objects):
            try:
                scene = finer_for_export(scene, voxels)
            except InputError as exc:
                app.say(str(exc), error=True)
                return False

        def write() -> str:
            used = export_render(scene, path, app.live.model_path, app.live.renderer, app.voxels, size)
            finest = max(o.resolution for o in scene.objects)
            return f"exported {Path(path).resolve()} ({used}, {finest}^3 voxels)"

        return self.write_file(path, overwrite, write)

    def export_side_by_side(self, path: str | Path, overwrite: bool = False) -> bool:
        """Write the viewport (as the user sees it, square) and the neural render of the committed scene side by side."""
        app = self.app

        def write() -> str:
            if app.jobs.current is not None or not app.synced:
                raise InputError("the viewport is not up to date yet: export again when the work in progress is done")
            scene = app.doc.history.current
            render, used = final_render(scene, app.live.model_path, app.live.renderer, app.voxels)
            height = render.shape[0] * side_by_side.scale_for(render.shape[0])
            viewport = app.viewport.image(height, height, viewport_camera(app.view, height, height), scene,
                                          app.floor_color)
            save_png(path, side_by_side.compose(viewport, to_uint8(render)))
            return f"exported the viewport and the render side by side to {Path(path).resolve()} ({used})"

        return self.write_file(path, overwrite, write)

    def export_vox(self, path: str | Path, overwrite: bool = False) -> bool:
        """Write the painted object voxels as a MagicaVoxel model (at most 255 colors)."""
        from renderer.vox import write_vox

        def write() -> str:
            rgba, _ = self.app.voxels.painted(self.app.object_view(self.app.doc.history.current))
            colors = write_vox(path, rgba)
            return f"exported {Path(path).resolve()} ({rgba.shape[0]}^3 voxels, {colors} colors)"

        return self.write_file(path, overwrite, write)

    def export_turntable(self, path: str | Path, frames: int = 36, sweep: str = "rotation", overwrite: bool = False) -> bool:
        """Render the committed scene turning (or the light circling) with the panel's renderer in the background,
        then write an animated GIF (`path` ends in .gif) or a folder of PNG frames; asks before replacing a GIF."""
        from app.turntable import TurntableConfig, render_turntable, write_frames

        app, target = self.app, Path(path)
        overwrite = overwrite or target.suffix.lower() != ".gif"  # a folder of frames is written into, not replaced
        if not self.may_replace(target, overwrite, lambda: self.export_turntable(path, frames, sweep, overwrite=True)):
            return False
        config = TurntableConfig(frames=frames, sweep=sweep, renderer=app.live.renderer, model=app.live.model_path)
        scene = app.doc.history.current

        def work(progress: Progress) -> str:
            images, seconds, name = render_turntable(scene, config, progress=False, on_frame=progress)
            write_frames(target, images)
            return f"exported {target.resolve()} ({frames} frames, {sweep} sweep, {name}, {1000 * sum(seconds) / len(seconds):.0f} ms a frame)"

        app.jobs.start(f"Turntable {target.name}", work, app.say)
        return True

    # --- objects from files -------------------------------------------------------------------

    def import_vox(self, path: str | Path, add: bool = False) -> None:
        """Make a MagicaVoxel model (its palette colors; the largest model of the file) the selected object, or with
        `add` a new object where the floor has room: one undo step. A file whose scene shows several models asks
        whether they all become the scene's objects, where the file places them."""
        from renderer.vox import read_vox, read_vox_scene

        def work(_progress: Progress) -> tuple[Path, int, list]:
            rgba = read_vox(path)
            models = read_vox_scene(path)
            # Kept in the state folder; Save copies them beside the scene.
            placed = [(model, state.save_capture(model.rgba)) for model in models] if len(models) > 1 else []
            return state.save_capture(rgba), rgba.shape[0], placed

        def done(result: tuple[Path, int, list]) -> None:
            voxels, n, placed = result
            if placed:
                self._offer_models(path, placed, lambda: one(voxels, n))
            else:
                one(voxels, n)

        def one(voxels: Path, n: int) -> None:
            app = self.app
            if add:
                named = ObjectSpec(voxels=str(voxels), resolution=n, name=Path(path).stem)
                done_ = app.edit(lambda s: edits.add_object(s, named), select=len(app.scene.objects))
            else:
                done_ = app.edit_object(lambda s: edits.replace_object_source(s, voxels=voxels, resolution=n))
            if done_:
                app.say(f"{'added' if add else 'imported'} {Path(path).name} ({n}^3 voxels)")

        self.app.jobs.start(f"Importing {Path(path).name}", work, done)

    def _offer_models(self, path: str | Path, placed: list, largest: Callable[[], None]) -> None:
        """Ask whether a .vox file's models all become the scene's objects (one undo step) or its largest alone."""
        from renderer.vox import placed_objects

        app = self.app
        if len(placed) > MAX_OBJECTS:
            app.say(f"{Path(path).name} shows {len(placed)} models; a scene holds at most {MAX_OBJECTS}: the largest "
                    "alone is imported")
            largest()
            return

        def choose(choice: str) -> None:
            if choice == "Largest alone":
                largest()
            elif choice == "All models":
                objects = placed_objects([m for m, _ in placed], [str(file) for _, file in placed])
                if app.edit(lambda s: s.with_changes(objects=objects), select=0):
                    app.say(f"imported {len(objects)} models of {Path(path).name} as the scene's objects")

        app.ask("Import the models", f"{Path(path).name} shows {len(placed)} models: "
                f"{', '.join(m.name for m, _ in placed)}. Import them all, where the file places them, in place of "
                "the scene's objects?", ("All models", "Largest alone", "Cancel"), choose)

    def load_mesh(self, path: str | Path, up: str = "y") -> None:
        """Voxelise a mesh in the background (progress in the window), then put it in place of the object."""
        app = self.app
        try:
            candidate = edits.replace_object_source(app.object_view(app.doc.history.current), mesh=Path(path), up=up)
        except InputError as exc:
            app.say(str(exc), error=True)
            return

        def done(_rgba) -> None:
            if app.edit_object(lambda s: edits.replace_object_source(s, mesh=Path(path), up=up)):
                app.say(f"loaded {Path(path).name}")
                app.warn_missing_materials(Path(path))

        app.jobs.start(f"Voxelising {Path(path).name}", lambda progress: app.voxels.object_rgba(candidate, progress), done)

    # --- writing ------------------------------------------------------------------------------

    def may_replace(self, path: str | Path, overwrite: bool, again: Callable[[], object]) -> bool:
        """Whether `path` may be written now; if it exists (and `overwrite` is not set) ask, and on Replace run `again`."""
        if Path(path).exists() and not overwrite:
            self.app.ask("Replace the file?", f"{path} exists. Replace it?", ("Replace", "Cancel"),
                         lambda choice: choice == "Replace" and again())
            return False
        return True

    def write_file(self, path: str | Path, overwrite: bool, write: Callable[[], str]) -> bool:
        """Run `write` (it returns the message to show), asking first whether to replace `path` if it exists."""
        if not self.may_replace(path, overwrite, lambda: self.write_file(path, True, write)):
            return False
        try:
            message = write()
        except InputError as exc:
            self.app.say(str(exc), error=True)
            return False
        self.app.say(message)
        return True
