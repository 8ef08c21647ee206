"""The Photo tab's commands: load a photo, align the object to it, color the object from it, take its view.

A loaded photo is a PhotoAlignment (app/editor/photo_capture.py): the photo and the pose the
user is aligning, by hand or with the search. The slow steps (loading the object's shape,
the search, the coloring) run as the editor's background jobs, so the window keeps drawing;
only coloring and taking the photo's view change the scene, each as one undo step. The
panel (photo_panel.py) and replay files (replay.py) call these commands.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import trimesh

from app.editor import edits, state
from app.editor.editor_parts import Editor
from app.editor.jobs import BackgroundJob, Progress
from app.editor.photo_capture import PhotoAlignment, object_shape, scene_with_photo_view, shape_key
from renderer.capture.align import Alignment
from renderer.capture.capture import Capture, disk_note, find_pose, fit_advice, segment_photo
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.scene import Scene
from renderer.voxel_cache import VoxelCache

Shape = tuple[trimesh.Trimesh, tuple, SilhouetteRenderer]  # the object's shape, its shape_key, its silhouettes


class PhotoTool:
    """The photo being aligned (None before one is loaded) and what can be done with it."""

    def __init__(self, app: Editor):
        self.app = app
        self.alignment: PhotoAlignment | None = None
        self._shape_tried: tuple | None = None  # shape_key last loaded (or tried) for the alignment
        self.job: BackgroundJob | None = None  # the last search or coloring, whose progress the tab shows

    def load(self, photo: str | Path, camera: str | Path | None = None) -> None:
        """Load a photo to align: its pose starts from the camera file when given, else from the scene's view."""
        scene = self.app.object_view(self.app.doc.history.current)
        voxels = self.app.voxels

        def work(_progress: Progress) -> PhotoAlignment:
            alignment = PhotoAlignment(photo, scene, camera)
            alignment.set_mesh(*load_shape(scene, voxels))
            return alignment

        def done(alignment: PhotoAlignment) -> None:
            self.alignment, self._shape_tried = alignment, alignment.mesh_key
            h, w = alignment.rgb.shape[:2]
            start = "its camera file" if camera else "the scene's view"
            lens = "" if alignment.focal_35mm is None else f", lens {alignment.focal_35mm:g} mm (EXIF)"
            self.app.say(f"loaded {Path(photo).name} ({w}x{h}{lens}), posed from {start}: align by hand on the photo, "
                         "or Align")

        self.app.jobs.start(f"Loading {Path(photo).name}", work, done)

    def adjust(self, change: Callable[[PhotoAlignment], None]) -> None:
        """Change the pose by hand (`change` calls turn, shift, zoom or set_pose on the alignment)."""
        alignment = self._needed()
        if alignment is not None:
            change(alignment)

    def align(self, from_scratch: bool = False) -> None:
        """Search the pose whose silhouette fits the photo: near the current pose, or over every rotation and elevation."""
        alignment = self._needed()
        if alignment is None:
            return
        if alignment.mesh is None:
            self.app.say("the object's shape is not loaded yet; try again when it is", error=True)
            return
        mesh, initial = alignment.mesh, None if from_scratch else alignment.pose

        def work(progress: Progress) -> Alignment:
            return find_pose(mesh, alignment.rgb, alignment.alpha, initial=initial, path=alignment.path,
                             focal_35mm=alignment.focal_35mm, progress=progress, **alignment.hints())

        def done(found: Alignment) -> None:
            alignment.floor_disk = found.floor_disk  # before set_pose, whose new revision redraws the overlay
            alignment.set_pose(found.pose)
            p = found.pose
            hints = alignment.hints()
            advice = fit_advice(found, any(v is not None for v in hints.values()))
            if advice:
                self.app.say(f"aligned, but {advice}", error=True)
                return
            on_disk = f" ({disk_note(found)}: outlined in blue)" if found.floor_disk > 0.0 else ""
            self.app.say(f"aligned {'from scratch' if from_scratch else 'from the pose'}{on_disk}: silhouette IoU "
                         f"{found.iou:.3f} in {found.seconds:.1f} s (rotation {p.rotation_deg:.1f} deg, "
                         f"elevation {p.camera.elevation_deg:.1f} deg)")

        self.job = self.app.jobs.start(f"Aligning to {alignment.path.name}", work, done)

    def color_object(self) -> None:
        """Recolor the object's voxels from the photo at the current pose: one undo step."""
        alignment = self._needed()
        if alignment is None:
            return
        scene, voxels = self.app.object_view(self.app.doc.history.current), self.app.voxels
        pose = alignment.pose  # as it is now: the user may go on dragging while the job runs

        def work(progress: Progress) -> tuple[Capture, Path]:
            rgba, _ = voxels.painted(scene)
            capture = alignment.colors(rgba, pose, progress)
            return capture, state.save_capture(capture.rgba)

        def done(result: tuple[Capture, Path]) -> None:
            capture, path = result
            alignment.set_light(capture)
            if self.app.edit_object(lambda s: recolored(s, path)):
                self.app.say(f"colored the object from {alignment.path.name}; {capture.light_note}")

        self.job = self.app.jobs.start(f"Coloring from {alignment.path.name}", work, done)

    def set_divide_light(self, divide: bool) -> None:
        """Whether coloring fits the photo's light and divides it out (the Photo tab's checkbox)."""
        alignment = self._needed()
        if alignment is not None:
            alignment.divide_light = divide

    def use_fitted_light(self) -> None:
        """Move the scene's light to where the last coloring fitted the photo's: one undo step."""
        alignment = self._needed()
        if alignment is not None and alignment.fitted_light is not None:
            position = alignment.fitted_light.position
            if self.app.edit(lambda s: edits.move_light(s, position)):
                self.app.say("the scene's light now stands where the photo's was fitted")

    def show_mask(self) -> None:
        """Segment the photo with the box and strokes in the background and show the mask over it."""
        alignment = self._needed()
        if alignment is None:
            return

        def work(_progress: Progress):
            return segment_photo(alignment.rgb, alignment.alpha, alignment.path, **alignment.hints())

        self.app.jobs.start(f"Segmenting {alignment.path.name}", work, alignment.set_mask)

    def match_view(self) -> None:
        """Place the object and set the camera elevation as in the photo: one undo step."""
        alignment = self._needed()
        if alignment is not None and self.app.edit_object(lambda s: scene_with_photo_view(s, alignment.pose)):
            self.app.say(f"the scene now shows {alignment.path.name}'s view")

    def follow_object(self) -> None:
        """Once a frame: when the object's shape changed (another mesh, undo), load the new one for the alignment."""
        alignment, app = self.alignment, self.app
        if alignment is None or app.jobs.current is not None:
            return
        scene = app.object_view(app.doc.history.current)
        key = shape_key(scene)
        if key == self._shape_tried:
            return
        self._shape_tried = key  # tried once: a shape that fails to load is reported once, not every frame
        voxels = app.voxels

        def done(shape: Shape) -> None:
            if self.alignment is alignment:
                alignment.set_mesh(*shape)

        app.jobs.start("Loading the object's shape for the photo", lambda _progress: load_shape(scene, voxels), done)

    def _needed(self) -> PhotoAlignment | None:
        if self.alignment is None:
            self.app.say("load a photo first (Photo tab)", error=True)
        return self.alignment


def recolored(scene: Scene, capture: Path) -> Scene:
    """The scene whose object takes the captured voxels (its mesh kept for the shape; paint strokes reset)."""
    return edits.replace_object_source(scene, mesh=scene.mesh_path(), voxels=capture, up=scene.object.up)


def load_shape(scene: Scene, voxels: VoxelCache) -> Shape:
    """The object's shape, its key and its silhouette renderer (built here, in a job: it takes up to a second)."""
    mesh = object_shape(scene, voxels)
    return mesh, shape_key(scene), SilhouetteRenderer(mesh)
