"""`nvr`: the command line of NVR Studio. Thin: parse arguments, call renderer/ and models/, print.

Every user error (bad file, impossible value) prints one line and exits with code 2.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from app.options import add_options, config_from
from models.renderers import EVALUATED, RENDERERS
from renderer.errors import InputError
from renderer.limits import DEFAULT_RESOLUTION, MAX_IMAGE_SIZE, MAX_RESOLUTION, MIN_IMAGE_SIZE, MIN_RESOLUTION

EXIT_USER_ERROR = 2
RENDERER_HELP = "; ".join(f"{name}: {entry.summary}" for name, entry in RENDERERS.items())


class OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage error is one line (the problem and where help is), exit 2, like every other refusal."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_USER_ERROR, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def _output_path(path: str, force: bool) -> Path:
    from renderer.io import check_writable

    return check_writable(path, overwrite=force)


def _warn(messages: list[str]) -> None:
    for message in messages:
        print(f"warning: {message}", file=sys.stderr)


def _material_warnings(mesh_path) -> list[str]:
    from renderer.mesh import missing_material_files

    return [f"{mesh_path}: material file {name} not found: the mesh has no colors (grey)"
            for name in missing_material_files(mesh_path)] if mesh_path else []


# --- nvr render ---------------------------------------------------------------------------


def cmd_render(args: argparse.Namespace) -> None:
    from models.renderers import RendererOptions, correction_note, fixed_size, make_renderer
    from renderer.io import save_png
    from renderer.scene import load_scene, range_warnings

    if args.size is not None and not MIN_IMAGE_SIZE <= args.size <= MAX_IMAGE_SIZE:
        raise InputError(f"--size must be from {MIN_IMAGE_SIZE} to {MAX_IMAGE_SIZE} pixels, got {args.size}")
    scene = load_scene(args.scene)
    out = _output_path(args.output, args.force)
    size = args.size or scene.image_size
    start = time.perf_counter()
    renderer = make_renderer(args.renderer, RendererOptions(
        model=args.model, precision=args.precision, device=args.device, quality=args.quality, spp=args.spp,
        seed=args.seed, denoise=args.denoise))
    own = fixed_size(renderer)
    if own is not None and size != own:
        asked = f"--size {size}" if args.size is not None else f"the scene's image_size {size}"
        raise InputError(f"the model renders {own}x{own}; {asked} is not supported (pass --size {own})",
                         "--size" if args.size is not None else args.scene)
    try:
        image = renderer.render_sized(scene, size)
    except InputError as exc:  # a problem in what the scene asks for (a paint seed on no voxel): name the scene
        if exc.path is not None:
            raise
        raise InputError(exc.problem, args.scene) from None
    elapsed = time.perf_counter() - start
    save_png(out, image)
    print(f"wrote {out} ({size}x{size}, {args.renderer}, {renderer.description}{correction_note(renderer, size)}, "
          f"{elapsed:.2f} s)")
    note = renderer.last_report.note if renderer.last_report is not None else ""  # e.g. a scene the network does not read
    materials = [w for o in scene.objects for w in _material_warnings(scene.file(o.mesh))]
    _warn(range_warnings(scene) + ([note] if note else []) + materials)  # after the image


def add_render_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("render", help="render a scene file to a PNG")
    p.add_argument("scene", help="scene file (JSON, version 1 or 2)")
    p.add_argument("-o", "--output", required=True, help="PNG to write")
    p.add_argument("--renderer", choices=list(RENDERERS), default="nvr+", help=RENDERER_HELP)
    p.add_argument("--size", type=int, default=None, help="image side in pixels (default: the scene's)")
    p.add_argument("--spp", type=int, default=64, help="path tracing: samples per pixel")
    p.add_argument("--seed", type=int, default=0, help="path tracing: random seed (same seed, same image)")
    p.add_argument("--denoise", action="store_true", help="path tracing: Intel Open Image Denoise")
    p.add_argument("--model", default=None, help="network weights (.safetensors); default: the shipped model")
    p.add_argument("--precision", choices=["auto", "fp32", "bf16"], default="auto",
                   help="network arithmetic (auto: bf16 on CPUs with native bfloat16, else fp32)")
    p.add_argument("--device", default="auto", help="network device: auto (a CUDA GPU if there is one), cpu or cuda")
    _add_quality_argument(p)
    p.add_argument("--force", action="store_true", help="overwrite the output file if it exists")
    p.set_defaults(func=cmd_render)


# --- nvr voxelize / info ------------------------------------------------------------------


def cmd_voxelize(args: argparse.Namespace) -> None:
    from renderer.mesh import load_mesh, normalise_mesh
    from renderer.voxels import save_voxels, voxelize

    out = _output_path(args.output, args.force)
    mesh = normalise_mesh(load_mesh(args.mesh, up=args.up))
    _warn(_material_warnings(args.mesh))
    rgba = voxelize(mesh, resolution=args.res)
    save_voxels(out, rgba)
    occupied = int((rgba[..., 3] > 0.5).sum())
    print(f"wrote {out} ({args.res}^3 voxels, {occupied} occupied, from {len(mesh.faces)} faces)")


def add_voxelize_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("voxelize", help="voxelise a mesh into an RGBA grid (.npz)")
    p.add_argument("mesh", help="OBJ, PLY, STL, OFF, GLB or GLTF file")
    p.add_argument("-o", "--output", required=True, help=".npz to write (key 'rgba', N^3 x 4)")
    p.add_argument("--res", type=int, default=DEFAULT_RESOLUTION, help=f"voxels per side (default {DEFAULT_RESOLUTION})")
    p.add_argument("--up", choices=["y", "z"], default="y", help="the mesh's up axis")
    p.add_argument("--force", action="store_true", help="overwrite the output file if it exists")
    p.set_defaults(func=cmd_voxelize)


def cmd_capture(args: argparse.Namespace) -> None:
    from renderer.capture.capture import capture_appearance, captured_scene, disk_note, fit_advice
    from renderer.capture.pose import load_pose, save_pose
    from renderer.io import load_image, photo_focal_35mm
    from renderer.mesh import load_mesh, normalise_mesh
    from renderer.scene import save_scene
    from renderer.voxels import save_voxels, voxelize

    light = None if args.light is None else _parse_numbers(args.light, 3, "--light", "x,y,z")
    scene_out = _output_path(args.output, args.force)
    stem = scene_out.with_suffix("")
    voxels_out = _output_path(f"{stem}_colors.npz", args.force)
    camera_out = _output_path(f"{stem}_camera.json", args.force)
    mesh = normalise_mesh(load_mesh(args.mesh, up=args.up))
    photo, alpha = load_image(args.photo)
    pose = None if args.camera is None else load_pose(args.camera)
    focal_35mm = photo_focal_35mm(args.photo) if pose is None else None  # a camera file states its own lens
    search = args.auto or pose is None
    rgba = voxelize(mesh, resolution=args.res)
    box = _parse_box(args.box, photo.shape)
    captured = capture_appearance(rgba, mesh, photo, alpha, pose, search=search, path=args.photo,
                                  free_focal=args.free_focal, box=box, light=light,
                                  fit_photo_light=not args.keep_photo_light, focal_35mm=focal_35mm)
    save_voxels(voxels_out, captured.rgba)
    save_pose(camera_out, captured.pose)
    save_scene(captured_scene(args.mesh, voxels_out, captured.pose, args.up, args.res), scene_out)
    p = captured.pose
    how = "camera file" if captured.alignment is None else (
        f"{'refined' if pose else 'found'}: silhouette IoU {captured.alignment.iou:.3f} in {captured.alignment.seconds:.1f} s")
    print(f"pose ({how}): rotation {p.rotation_deg:.1f} deg, elevation {p.camera.elevation_deg:.1f} deg, "
          f"translation [{p.translation[0]:.3f}, {p.translation[1]:.3f}], scale {p.scale[0]:.3f}, "
          f"focal length {p.camera.focal_mm:.1f} mm"
          + ("" if focal_35mm is None else f" (the photo's EXIF: {focal_35mm:g} mm, 35 mm equivalent)"))
    note = "" if captured.alignment is None else disk_note(captured.alignment)
    if note:
        print(f"note: {note}")
    advice = None if captured.alignment is None else fit_advice(captured.alignment, box is not None)
    if advice:
        print(f"warning: {advice}")
    seen = int(captured.visible.sum())
    occupied = int((captured.rgba[..., 3] > 0.5).sum())
    mirror = "used" if captured.mirror_used else "not used"
    print(f"colors: {seen} of {occupied} voxels seen in the photo; mirror copy {mirror} "
          f"(symmetry IoU {captured.mirror_score:.2f}); {captured.light_note}")
    print(f"wrote {scene_out}, {voxels_out}, {camera_out}")


def add_capture_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("capture", help="capture an object's appearance from a photo into a scene")
    p.add_argument("mesh", help="the object's mesh (OBJ, PLY, STL, OFF, GLB or GLTF)")
    p.add_argument("photo", help="a photo of the object (PNG or JPEG; alpha marks the object if present)")
    p.add_argument("--camera", default=None, help="the photo's camera file (JSON); without --auto it is used as is")
    p.add_argument("--auto", action="store_true",
                   help="find the pose from the object's silhouette (from --camera's pose if given, else from none)")
    p.add_argument("--free-focal", action="store_true",
                   help="the search also fits the focal length (default: the photo's EXIF lens, else 40 mm)")
    p.add_argument("--light", default=None, metavar="X,Y,Z",
                   help="the light's centre when the photo was taken (world units; default: the camera file's "
                        "light, if any): its light is then divided out of the colors")
    p.add_argument("--keep-photo-light", action="store_true",
                   help="without a known light, colors keep the photo's shading (default: the light is fitted from "
                        "the photo and divided out)")
    p.add_argument("--box", default=None, metavar="X0,Y0,X1,Y1",
                   help="the object's box in photo pixels: outside it is background (needed on cluttered photos)")
    p.add_argument("--up", choices=["y", "z"], default="y", help="the mesh's up axis")
    p.add_argument("--res", type=int, default=DEFAULT_RESOLUTION, help=f"object voxels per side (default {DEFAULT_RESOLUTION})")
    p.add_argument("-o", "--output", required=True, help="scene file to write; NAME_colors.npz and NAME_camera.json go beside it")
    p.add_argument("--force", action="store_true", help="overwrite the output files if they exist")
    p.set_defaults(func=cmd_capture)


def _parse_numbers(text: str, count: int, option: str, form: str) -> tuple[float, ...]:
    """An option of `count` comma-separated finite numbers."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise InputError(f"{option} takes {form} ({count} numbers), got {text!r}")
    return values


def _parse_box(text: str | None, shape) -> tuple[int, int, int, int] | None:
    """--box x0,y0,x1,y1: the object's box in photo pixels (x right, y down), inside the photo."""
    if text is None:
        return None
    try:
        x0, y0, x1, y1 = (int(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--box takes x0,y0,x1,y1 in pixels, got {text!r}") from None
    h, w = shape[:2]
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise InputError(f"--box {text} must lie inside the {w}x{h} photo with x0 < x1 and y0 < y1")
    return x0, y0, x1, y1


def cmd_info(args: argparse.Namespace) -> None:
    from models.networks.checkpoint import check_weights_file
    from models.networks.nvr import reads_scene
    from models.networks.shipped import shipped_weights
    from renderer.pipeline import painted_objects, scene_grid_for
    from renderer.scene import load_scene, range_warnings

    scene = load_scene(args.scene)
    painted = painted_objects(scene)
    grid = scene_grid_for(scene, painted, scene.floor.color)
    grid_count = int((grid[..., 3] > 0.5).sum())
    print(f"scene      {args.scene}")
    for i, (o, rgba) in enumerate(zip(scene.objects, painted)):
        name = "object" if len(scene.objects) == 1 else f"object {i}" + ("" if o.name is None else f" ({o.name})")
        print(f"{name:<10} {o.voxels or o.mesh} (up {o.up}, {o.resolution}^3 voxels, "
              f"{int((rgba[..., 3] > 0.5).sum())} occupied)")
        print(f"  color    {'mesh colors' if o.color is None else list(o.color)}; {len(o.paint)} paint operations")
        print(f"  placed   translation {list(o.translation)}, rotation {o.rotation_deg:g} deg, scale {list(o.scale)}")
        m = o.material
        print(f"  material {'matte' if m.diffuse_only else f'roughness {m.roughness:g}, specular {m.specular:g}, metallic {m.metallic:g}'}")
    floor = scene.floor
    look = (f"color {list(floor.color)}" if floor.texture is None
            else f"texture {scene.floor_texture_path()} repeated every {floor.texture_scale:g} units")
    print(f"floor      {look}; {floor.shape}")
    print(f"light      position {list(scene.light.position)}{'' if scene.light.enabled else ' (off)'}")
    env = scene.environment
    if env is None:
        print("sky        the uniform ambient light")
    else:
        if env.sky is not None:
            s = env.sky
            what = (f"sun and sky: sun at {s.sun_elevation_deg:g} deg elevation, {s.sun_azimuth_deg:g} deg azimuth, "
                    f"turbidity {s.turbidity:g}")
        else:
            what = f"environment image {scene.environment_path()}"
        print(f"sky        {what}; turned {env.rotation_deg:g} deg, strength {env.strength:g}")

    print(f"camera     elevation {scene.camera.elevation_deg:g} deg; image {scene.image_size}x{scene.image_size}")
    print(f"voxels     scene grid {grid_count} of {grid.shape[0]}^3 occupied")
    warnings = range_warnings(scene)
    print("training   all values inside the training ranges" if not warnings else "training   outside the training ranges:")
    for message in warnings:
        print(f"  - {message}")
    # What the default renderer draws: the shipped network's own config says which scenes it reads.
    _, config, _ = check_weights_file(shipped_weights("nvr_plus"))
    if reads_scene(config, scene):
        print("network    the shipped NVR+ corrects the voxel shader's image")
    else:
        print("network    the shipped NVR+ is not trained for environments, gloss or floor textures: "
              "for this scene it shows the voxel shader's image")


def add_info_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="what a scene holds, its voxel counts, values outside the training range")
    p.add_argument("scene")
    p.set_defaults(func=cmd_info)


# --- nvr import-vox / export-vox ---------------------------------------------------------


def cmd_import_vox(args: argparse.Namespace) -> None:
    from renderer.limits import MAX_OBJECTS
    from renderer.scene import ObjectSpec, Scene, save_scene
    from renderer.vox import placed_objects, read_vox, read_vox_scene
    from renderer.voxels import save_voxels

    scene_out = _output_path(args.output, args.force)
    voxels_out = _output_path(f"{scene_out.with_suffix('')}_voxels.npz", args.force)
    models = read_vox_scene(args.model_file) if args.model is None else []
    if len(models) > 1:  # every model the file's scene shows, where it stands
        if len(models) > MAX_OBJECTS:
            raise InputError(f"shows {len(models)} models; a scene holds at most {MAX_OBJECTS} (pick one with --model)",
                             args.model_file)
        files = [voxels_out] + [_output_path(f"{scene_out.with_suffix('')}_voxels{k}.npz", args.force)
                                for k in range(1, len(models))]
        for model, file in zip(models, files):
            save_voxels(file, model.rgba)
        save_scene(Scene(objects=placed_objects(models, [str(f.resolve()) for f in files]), base_dir=Path(".")),
                   scene_out)
        print(f"wrote {scene_out} and {len(files)} voxel files ({len(models)} models as objects: "
              f"{', '.join(m.name for m in models)})")
        return
    rgba = read_vox(args.model_file, model=args.model)
    save_voxels(voxels_out, rgba)
    n = rgba.shape[0]
    scene = Scene.single(object=ObjectSpec(voxels=str(voxels_out.resolve()), resolution=n), base_dir=Path("."))
    save_scene(scene, scene_out)
    print(f"wrote {scene_out} and {voxels_out} ({n}^3 voxels, {int((rgba[..., 3] > 0.5).sum())} occupied)")


def add_import_vox_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("import-vox", help="a MagicaVoxel .vox file as a scene: its models as objects where the file "
                                         "places them, in their palette colors")
    p.add_argument("model_file", metavar="MODEL.vox")
    p.add_argument("-o", "--output", required=True,
                   help="scene file to write; NAME_voxels.npz (NAME_voxels1.npz ... for more models) go beside it")
    p.add_argument("--model", type=int, default=None,
                   help="one model of a multi-model file alone, from 0 (default: every model the file shows)")
    p.add_argument("--force", action="store_true", help="overwrite the output files if they exist")
    p.set_defaults(func=cmd_import_vox)


def cmd_export_vox(args: argparse.Namespace) -> None:
    from renderer.pipeline import object_voxels, painted_voxels
    from renderer.scene import load_scene
    from renderer.vox import write_vox

    scene = load_scene(args.scene)
    out = _output_path(args.output, args.force)
    rgba, _ = painted_voxels(scene, object_voxels(scene))
    colors = write_vox(out, rgba)
    print(f"wrote {out} ({rgba.shape[0]}^3 voxels, {int((rgba[..., 3] > 0.5).sum())} occupied, {colors} palette colors)")


def add_export_vox_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export-vox", help="a scene's painted object voxels as a MagicaVoxel .vox model")
    p.add_argument("scene")
    p.add_argument("-o", "--output", required=True, help=".vox file to write (at most 255 colors)")
    p.add_argument("--force", action="store_true", help="overwrite the output file if it exists")
    p.set_defaults(func=cmd_export_vox)


# --- nvr turntable -----------------------------------------------------------------------


def cmd_turntable(args: argparse.Namespace) -> None:
    from app.turntable import TurntableConfig, render_turntable, write_frames
    from renderer.scene import load_scene

    config = config_from(TurntableConfig, args)
    config.check()
    out = Path(args.output)
    if out.suffix.lower() == ".gif":
        _output_path(args.output, args.force)
    elif out.exists() and (not out.is_dir() or (any(out.glob("frame_*.png")) and not args.force)):
        raise InputError("holds frames already (pass --force to replace them)" if out.is_dir() else "is not a folder", out)
    scene = load_scene(args.scene)
    images, seconds, name = render_turntable(scene, config)
    written = write_frames(out, images)
    rest = sorted(seconds[1:])
    timing = f"first frame {1000 * seconds[0]:.0f} ms" + (
        f", then median {1000 * rest[len(rest) // 2]:.0f} ms a frame" if rest else "")
    print(f"wrote {out if len(written) == 1 else f'{len(written)} frames to {out}'} ({config.frames} frames, "
          f"{config.sweep} sweep, {name}; {timing})")


def add_turntable_parser(sub: argparse._SubParsersAction) -> None:
    from app.turntable import TurntableConfig

    p = sub.add_parser("turntable", help="the object turning (or the light circling) as an animated GIF or PNG frames")
    p.add_argument("scene")
    p.add_argument("-o", "--output", required=True, help="OUT.gif, or a folder for frame_0000.png ...")
    add_options(p, TurntableConfig)
    p.add_argument("--force", action="store_true", help="replace an existing GIF or frames")
    p.set_defaults(func=cmd_turntable)


# --- nvr data ----------------------------------------------------------------------------


def cmd_data_generate(args: argparse.Namespace) -> None:
    from renderer.dataset import DataConfig, generate_dataset, parse_shard

    manifest = generate_dataset(args.out, config_from(DataConfig, args), shard=parse_shard(args.shard),
                                workers=args.workers)
    print(f"wrote {manifest}")


def cmd_data_recolor(args: argparse.Namespace) -> None:
    from renderer.dataset import recolor_dataset

    manifest = recolor_dataset(args.data, args.out, workers=args.workers, hidden_rule=args.hidden_voxels,
                               resolution=args.res, delight_shader=args.delight_shader,
                               photo_size=args.photo_size)
    print(f"wrote {manifest}")


def cmd_data_merge(args: argparse.Namespace) -> None:
    from renderer.dataset import merge_datasets

    print(f"wrote {merge_datasets(args.out, args.parts)}")


def add_data_parser(sub: argparse._SubParsersAction) -> None:
    from renderer.dataset_config import HIDDEN_RULES, MADE_DELIGHT_SHADERS, DataConfig

    data = sub.add_parser("data", help="make training and test sets").add_subparsers(dest="data_command", required=True)
    p = data.add_parser("generate", help="render objects and views after the paper's protocol")
    p.add_argument("--out", required=True, help="data folder (created; rerun to resume)")
    add_options(p, DataConfig)
    p.add_argument("--shard", default=None, help="I/N: make only part I of N (merge the parts afterwards)")
    p.add_argument("--workers", type=int, default=1, help="parallel processes")
    p.set_defaults(func=cmd_data_generate)
    p = data.add_parser("merge", help="merge shard folders into one data set")
    p.add_argument("--out", required=True)
    p.add_argument("parts", nargs="+", help="shard folders")
    p.set_defaults(func=cmd_data_merge)
    p = data.add_parser("recolor", help="copy a data set whose photo colors other rules made (light kept, or the "
                                        "other rule for hidden voxels), recoloring its voxels with the light divided "
                                        "out and the --hidden-voxels rule; --res: at another voxel resolution")
    p.add_argument("data", help="the data folder to copy (left unchanged)")
    p.add_argument("--out", required=True, help="new data folder (rerun to resume); targets are hard links")
    p.add_argument("--workers", type=int, default=1, help="parallel processes")
    p.add_argument("--hidden-voxels", choices=HIDDEN_RULES, default=HIDDEN_RULES[0],
                   help="the rule for voxels the source photo does not show (as for generate)")
    p.add_argument("--delight-shader", choices=MADE_DELIGHT_SHADERS, default=MADE_DELIGHT_SHADERS[0],
                   help="how the source photo's light is divided out (as for generate)")
    p.add_argument("--res", type=int, default=None,
                   help="voxelise every object anew at this many voxels per side (its mesh remade from its record; "
                        "its targets kept); default: keep the set's voxels")
    p.add_argument("--photo-size", type=int, default=None,
                   help="path trace every source photo again at this side in pixels (0: the images' size); "
                        "default: keep the set's photos")
    p.set_defaults(func=cmd_data_recolor)


# --- nvr train / eval ----------------------------------------------------------------------


def cmd_train(args: argparse.Namespace) -> None:
    from models.engine import resolve_precision  # before torch, so OMP_WAIT_POLICY is set when torch loads OpenMP

    # isort: split
    import torch

    from models.training.train import TrainConfig, train

    precision = resolve_precision(args.precision, torch.device("cuda" if args.device.startswith("cuda") else "cpu"))
    config = config_from(TrainConfig, args, architecture=RENDERERS[args.model].architecture, precision=precision,
                         config_overrides=tuple(_parse_overrides(args.set)))
    print(f"wrote {train(args.out, config, resume=args.resume)}")


def add_train_parser(sub: argparse._SubParsersAction) -> None:
    from models.training.config import TrainConfig

    p = sub.add_parser("train", help="train NVR or NVR+ on data folders (resumable; torchrun for DDP)")
    p.add_argument("--out", required=True, help="run folder")
    p.add_argument("--model", choices=[n for n, e in RENDERERS.items() if e.architecture], default="nvr+")
    add_options(p, TrainConfig)
    p.add_argument("--precision", choices=["auto", "fp32", "bf16"], default="auto",
                   help="the forward pass in bf16 autocast, weights and Adam in fp32 (auto: bf16 on CPUs with native "
                        "bfloat16, else fp32)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a network config field, e.g. --set grid_size=64 (repeatable)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    p.set_defaults(func=cmd_train)


def cmd_distill(args: argparse.Namespace) -> None:
    import models.engine  # noqa: F401 - before torch, so OMP_WAIT_POLICY is set when torch loads OpenMP
    from models.training.distill import DistillConfig, distill

    out = _output_path(args.out, args.force)
    measured = distill(out, config_from(DistillConfig, args))
    print(f"wrote {out}: the teacher's decoder features on {measured['held_out_latents']} held-out latents with "
          f"relative error {measured['relative_error']:.4f} (cut, before training: {measured['relative_error_start']:.4f})")


def add_distill_parser(sub: argparse._SubParsersAction) -> None:
    from models.training.config import DistillConfig

    p = sub.add_parser("distill", help="an NVR+ with fewer residual blocks after the light merge (a faster light "
                                       "edit), trained to give a trained one's features; no rendered data needed")
    add_options(p, DistillConfig)
    p.add_argument("--out", required=True, help="weights file to write")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.set_defaults(func=cmd_distill)


def _parse_overrides(items: list[str]) -> list[tuple[str, object]]:
    """--set KEY=VALUE pairs (VALUE as JSON: 16, [8, 16], 0.5) for network config fields."""
    import json

    pairs = []
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise InputError(f"--set expects KEY=VALUE, got {item!r}")
        try:
            parsed = json.loads(value)
        except json.JSONDecodeError:
            raise InputError(f"--set {key}: value {value!r} is not a number or list") from None
        pairs.append((key, tuple(parsed) if isinstance(parsed, list) else parsed))
    return pairs


def cmd_eval(args: argparse.Namespace) -> None:
    from models.evaluation.evaluate import evaluate

    if args.limit < 0:
        raise InputError(f"--limit must be 0 (all samples) or a positive number of samples, got {args.limit}")
    resolutions = _parse_resolutions(args.resolution_study) if args.resolution_study else None
    out = _output_path(args.report, args.force)
    if resolutions:
        from models.evaluation.evaluate import resolution_study

        print(f"wrote {resolution_study(args.data, args.model, args.renderer, resolutions, out, limit=args.limit)}")
        return
    written = evaluate(args.data, args.model, args.renderer, out, limit=args.limit, shading_grid=args.shading_grid,
                       shader_quality=args.quality)
    print(f"wrote {written}")


def add_eval_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="table 1 metrics of a model (or the splat baseline) on a test split")
    p.add_argument("--data", required=True, nargs="+", help="test data folders")
    p.add_argument("--model", default=None, help="weights (.safetensors); default: the shipped model")
    p.add_argument("--renderer", choices=list(EVALUATED), default="nvr+")
    p.add_argument("--report", required=True, help="Markdown report to write (a figure is written beside it)")
    p.add_argument("--limit", type=int, default=0, help="evaluate at most this many samples (0: all)")
    p.add_argument("--shading-grid", type=int, default=256, metavar="N",
                   help="the grid the shaded renderer stands in for: 256 (the object's voxels unmerged, the editor's) "
                        "or 128 (the network's: merged in pairs, faster)")
    _add_quality_argument(p)
    p.add_argument("--resolution-study", default=None, metavar="100,75,50,25",
                   help="instead: the metrics with object voxels downsampled to each resolution (paper table 2)")
    p.add_argument("--force", action="store_true", help="overwrite the report if it exists")
    p.set_defaults(func=cmd_eval)


def _add_quality_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quality", choices=["full", "fast"], default="full",
                   help="the voxel shader's (shaded, nvr+): full, as the networks were trained; fast: one ray per "
                        "silhouette pixel, 2 x 2 light points, normals from the smoothed field alone, one voxel's color "
                        "a point, no ambient occlusion: faster, less accurate")


def _parse_resolutions(text: str) -> list[int]:
    """--resolution-study's list, e.g. "100,75,50,25": object voxels per side, each a possible resolution."""
    try:
        resolutions = [int(r) for r in text.split(",")]
    except ValueError:
        raise InputError(f"--resolution-study takes a list like 100,75,50,25, got {text!r}") from None
    if not all(MIN_RESOLUTION <= r <= MAX_RESOLUTION for r in resolutions):
        raise InputError(f"--resolution-study resolutions must be from {MIN_RESOLUTION} to {MAX_RESOLUTION}, got {text!r}")
    return resolutions


# --- nvr bench ------------------------------------------------------------------------------


def cmd_bench(args: argparse.Namespace) -> None:
    from models.bench.benchmark import DOCS, FULL, QUICK, report_files, run_bench, write_outputs

    folder = Path(args.report) if args.report else Path("out") / ("bench-quick" if args.quick else "bench")
    if args.quick and folder.resolve() == DOCS:
        raise InputError(f"{folder}: a --quick run's one-scene numbers do not replace the benchmark page; "
                         "give --report another folder")
    if not folder.is_dir():
        try:
            folder.mkdir(parents=True)
        except OSError as exc:
            raise InputError(f"cannot create the report folder: {exc.strerror}", folder) from None
    paths = report_files(folder)
    for path in paths:
        _output_path(str(path), args.force)
    results = run_bench(QUICK if args.quick else FULL, data=args.data, model_paths=args.model, note=args.note)
    write_outputs(results, folder)
    print(f"wrote {', '.join(str(path) for path in paths)}: light edit "
          f"{results['nvrplus_light_edit_ms']:.1f} ms, frame {results['nvrplus_frame_ms']:.1f} ms, "
          f"path tracing 1 spp + OIDN {results['pathtrace_1spp_oidn_ms']:.1f} ms")


def add_bench_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="every renderer on the same scenes: time, memory and error, as a report")
    p.add_argument("--data", nargs="+", default=None, help="test data folders to take scenes from (default: procedural)")
    p.add_argument("--model", action="append", default=None, help="weights to include (repeatable; default: assets/models)")
    p.add_argument("--quick", action="store_true", help="a CI-sized subset (one scene, 1 and 4 spp, no paper config)")
    p.add_argument("--report", default=None, metavar="DIR",
                   help="folder for benchmarks.md, benchmarks.json and speed_vs_error.png (default out/bench, "
                        "or out/bench-quick with --quick); `--report docs` updates the project's page (full runs "
                        "only; a CPU with native bfloat16 writes benchmarks_avx512_bf16.md and its files)")
    p.add_argument("--force", action="store_true", help="replace an earlier report in that folder")
    p.add_argument("--note", default="", help="a line for the report, e.g. what else ran on the machine")
    p.set_defaults(func=cmd_bench)


# --- the command line ------------------------------------------------------------------------

COMMANDS = (add_render_parser, add_voxelize_parser, add_capture_parser, add_import_vox_parser, add_export_vox_parser,
            add_turntable_parser, add_data_parser, add_train_parser, add_distill_parser, add_eval_parser,
            add_bench_parser, add_info_parser)


def build_parser() -> argparse.ArgumentParser:
    """`nvr` and its commands, each added by the add_<command>_parser beside the command."""
    parser = OneLineParser(prog="nvr", description="NVR Studio: neural voxel rendering tools.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS:
        add(sub)
    return parser


def run(argv: list[str] | None = None) -> int:
    """Parse and run; returns the exit code (0, or 2 for a user error)."""
    args = build_parser().parse_args(argv)
    from models.threads import limit_blas_threads

    limit_blas_threads()
    try:
        args.func(args)
    except InputError as exc:
        print(f"nvr: error: {exc}", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("nvr: interrupted", file=sys.stderr)
        return 130
    return 0


def main() -> None:
    sys.exit(run())


if __name__ == "__main__":  # `torchrun ... -m app.cli train ...` for multi-process training
    main()
