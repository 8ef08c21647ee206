"""`nvr eval`: the paper's table 1 metrics of a renderer over test folders, per appearance setting.

The renderer is a trained NVR or NVR+ (weights file) or the splat baseline (the splatted image S
itself). Writes a Markdown report and, beside it, a figure of the inputs (splat), prediction and
target for each setting's typical (median error) and worst view. The report also says how much of
the squared error lies off the object (pixels where the splat shows only floor or sky), and lists
each object's mean error over its views, worst first: one object can dominate a setting.
"""

from __future__ import annotations

import platform
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import torch

from models.evaluation.metrics import ImageMetrics
from models.networks.nvr import NVRPlus, reads_floor_light, reads_scene, reads_shading
from models.networks.shipped import shipped_weights
from models.renderers import renderer_entry
from models.training.data import VoxelRenderSet, read_manifest
from renderer.errors import InputError
from renderer.io import atomic_path, save_png
from renderer.scene import GRID_SIZE, SHADER_GRID_SIZE
from renderer.shading import quality_named, shadows_of_others

METRICS = ("mse", "dssim", "perceptual")


def _load_renderer(model_path: str | None, renderer: str):
    """(model, config, extra) of a network renderer, or Nones for the splat and the shader."""
    from models.networks.checkpoint import load_model

    architecture = renderer_entry(renderer).architecture
    if architecture is None:
        return None, None, {}
    path = Path(model_path) if model_path else shipped_weights(architecture)
    model, config, extra = load_model(path)
    if model.architecture != architecture:
        raise InputError(f"holds a {model.architecture} network, not {architecture}", path)
    return model, config, extra


def evaluate(data: list[str], model_path: str | None, renderer: str, report: str | Path, limit: int = 0,
             shading_grid: int = SHADER_GRID_SIZE, shader_quality: str = "full") -> Path:
    """Compute MSE, DSSIM and perceptual per setting; write the report and figure; return the report path.
    `shading_grid`: the side of the grid the 'shaded' renderer stands in for (a multiple of the network grid's 128);
    `shader_quality`: the shader's silhouette rays and light points (renderer.shading.QUALITIES), for both."""
    report = Path(report)
    if shading_grid < GRID_SIZE or shading_grid % GRID_SIZE:
        raise InputError(f"--shading-grid must be a multiple of {GRID_SIZE}, got {shading_grid}")
    quality_named(shader_quality)  # a clear message for an unknown name before any work
    model, config, extra = _load_renderer(model_path, renderer)
    if renderer_entry(renderer).kind == "shader":
        extra = {"shading_grid": f"{shading_grid}^3"}
    elif model is not None and reads_shading(model.architecture, config):
        extra = {**extra, "shading_grid": f"{config.shading_grid_size}^3"}
    if shader_quality != "full" and "shading_grid" in extra:
        extra["shader_quality"] = shader_quality
    metrics = ImageMetrics()
    started = time.perf_counter()
    scores, (rows, captions), count = _score(data, model, config, renderer, metrics, limit,
                                             shading_grid_factor=shading_grid // GRID_SIZE, shader_quality=shader_quality)
    seconds = time.perf_counter() - started
    figure = report.with_suffix(".png")
    if rows:
        save_png(figure, torch.cat(rows, dim=1).permute(1, 2, 0).numpy())
    with_floor_light = model is not None and reads_floor_light(model.architecture, config)
    with_shading = model is not None and reads_shading(model.architecture, config)
    columns = ", ".join(["splat"] + ["lit floor"] * with_floor_light + ["shaded"] * with_shading + ["prediction", "target"])
    if config is not None and config.environment_input:
        extra = {**extra, "environment_input": True}
    _write_report(report, figure, columns, captions, renderer, model_path, extra, scores,
                  metrics.perceptual.weights_name, count, seconds, data)
    return report


def resolution_study(data: list[str], model_path: str | None, renderer: str, resolutions: list[int],
                     report: str | Path, limit: int = 0) -> Path:
    """The paper's table 2: the same test set with object voxels at coarser resolutions."""
    report = Path(report)
    for folder in data:
        stored = read_manifest(folder).get("config", {}).get("resolution")
        if isinstance(stored, int) and max(resolutions) > stored:
            raise InputError(f"holds {stored}^3 object voxels; --resolution-study can only go down from there, "
                             f"got {max(resolutions)}", folder)
    model, config, extra = _load_renderer(model_path, renderer)
    lines = [f"# Voxel resolution study: {renderer}", "",
             f"- model: {model_path or 'shipped'}; data: {', '.join(map(str, data))}",
             "- object voxels block-downsampled from the data set's resolution (renderer.voxels.downsample_voxels)",
             "", "| object voxels | samples | MSE (0-255) | DSSIM | perceptual |", "|---:|---:|---:|---:|---:|"]
    metrics = ImageMetrics()
    for resolution in resolutions:
        scores, _, count = _score(data, model, config, renderer, metrics, limit, object_resolution=resolution,
                                  figure=False)
        values = [v for per_setting in scores.values() for v in per_setting]
        mean = {k: float(np.mean([v[k] for v in values])) for k in METRICS}
        lines.append(f"| {resolution}^3 | {count} | {mean['mse']:.2f} | {mean['dssim']:.4f} | {mean['perceptual']:.3f} |")
    with atomic_path(report) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return report


def _score(data: list[str], model, config, renderer: str, metrics: ImageMetrics, limit: int,
           object_resolution: int | None = None, figure: bool = True, shading_grid_factor: int = 1,
           shader_quality: str = "full"):
    """Per-setting metric lists, the figure's rows with their captions (none without `figure`), and the sample count.
    `shading_grid_factor`: how much finer than the network's grid the 'shaded' renderer's grid is."""
    # The splat baseline reads no voxels; the shader reads the scene grid.
    shader = renderer_entry(renderer).kind == "shader"
    grid_size = GRID_SIZE if shader else 8 if config is None else config.grid_size
    with_floor_light = model is not None and reads_floor_light(model.architecture, config)
    with_shading = model is not None and reads_shading(model.architecture, config)
    dataset = VoxelRenderSet(data, grid_size=grid_size, object_resolution=object_resolution, floor_light=with_floor_light,
                             shading=with_shading,
                             shading_grid_factor=config.shading_grid_factor if with_shading else shading_grid_factor,
                             shader_quality=shader_quality,
                             environment=config is not None and config.environment_input)
    count = len(dataset) if limit <= 0 else min(limit, len(dataset))
    scores: dict[str, list[dict[str, float]]] = defaultdict(list)

    def predict(sample: dict, index: int) -> torch.Tensor:
        # A scene the network does not read shows the shader's image, as in the engine.
        if shader or (model is not None and not reads_scene(config, dataset.scene(index))):
            image = dataset.shaded(dataset.scene(index), dataset.object_voxels(index), sample["target"].shape[-1],
                                   reflection=True).image
            return torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1)))[None]
        if model is None:
            return sample["splat"][None]
        if sample["target"].shape[-1] != config.output_size:
            raise InputError(f"test images are {sample['target'].shape[-1]}^2 but the model renders {config.output_size}^2")
        # Only the inputs this network reads: NVR takes neither a splat nor the shader's buffers.
        inputs = {name: sample[name][None] for name, wanted in
                  (("splat", isinstance(model, NVRPlus)), ("floor_light", with_floor_light), ("shading", with_shading)) if wanted}
        return model(sample["voxels"][None], sample["light"][None], **inputs).clamp(0.0, 1.0)

    with torch.no_grad():
        for index in range(count):
            sample = dataset[index]
            prediction = predict(sample, index)
            values: dict = {k: float(v[0]) for k, v in metrics(prediction, sample["target"][None]).items()}
            folder, item = dataset.items[index]
            values["object"] = f"{folder.name}/{item.get('object', '?')}"
            values["sample"] = f"{folder.name}/{item.get('id', index)}"
            values["index"] = index
            values["ground_share"] = _ground_share(prediction[0], sample["target"], sample["splat"], dataset.scene(index))
            scene = dataset.scene(index)
            values["lighting"], values["material"] = lighting_label(scene), material_label(scene)
            values["ground"] = ground_label(scene)
            values["objects"] = len(scene.objects)
            if len(scene.objects) > 1:  # the error inside each object's shadow on the others, kept apart
                shadow = torch.from_numpy(shadows_of_others(scene, dataset.object_voxels(index), sample["target"].shape[-1],
                                                            shaders=dataset.shaders, keys=dataset.voxel_keys(scene)))
                squared = ((prediction[0] - sample["target"]) * 255.0) ** 2
                values["shadow_pixels"] = int(shadow.sum())
                values["shadow_squared"] = float(squared[:, shadow].mean()) if shadow.any() else 0.0
            scores[dataset.settings[index]].append(values)
        # The figure: each setting's typical view (median MSE) and its worst, drawn again (a few samples, not all kept).
        rows, captions = [], []
        for setting in sorted(scores) if figure else ():
            for label, chosen in _figure_samples(scores[setting]):
                index = chosen["index"]
                sample = dataset[index]
                inputs = ([sample["splat"]] + ([sample["floor_light"]] if with_floor_light else [])
                          + ([sample["shading"][:3]] if with_shading else []))
                rows.append(torch.cat([*inputs, predict(sample, index)[0], sample["target"]], dim=2))
                captions.append(f"{setting}, {label}: {chosen['sample']} (MSE {chosen['mse']:.1f})")
    return scores, (rows, captions), count


def lighting_label(scene) -> str:
    """What lights a test scene: the area light, a sky, or a made map's kind (its file's prefix), and whether the
    area light is on beside the environment."""
    env = scene.environment
    if env is None:
        return "area light"
    kind = "sky" if env.sky is not None else Path(env.image).name.split("_")[0]
    return f"{kind} + area light" if scene.light.enabled else kind


def material_label(scene) -> str:
    """The test scene's objects: all matte, or glossy, or metal (when any object is)."""
    materials = [o.material for o in scene.objects]
    if all(m.diffuse_only for m in materials):
        return "matte"
    return "metal" if any(m.metallic >= 0.5 for m in materials) else "glossy"


def ground_label(scene) -> str:
    """The test scene's ground: plain or textured, square or disk."""
    floor = scene.floor
    return f"{'plain' if floor.texture is None else 'textured'} {floor.shape}"


def _figure_samples(values: list[dict]) -> list[tuple[str, dict]]:
    """A setting's sample of median MSE and its sample of highest MSE, labelled."""
    by_error = sorted(values, key=lambda v: v["mse"])
    return [("typical view (median MSE)", by_error[(len(by_error) - 1) // 2]), ("worst view", by_error[-1])]


def _ground_share(prediction: torch.Tensor, target: torch.Tensor, splat: torch.Tensor, scene) -> float:
    """Share of the squared error on pixels where the splat shows no object (floor and sky)."""
    from renderer.camera import Camera
    from renderer.splat import floor_mask, ground_and_background

    size = splat.shape[-1]
    empty = ground_and_background(floor_mask(Camera.from_scene(scene, size)), scene.floor.color)
    ground = torch.from_numpy(np.abs(empty.transpose(2, 0, 1) - splat.numpy()).max(0) < 1.0 / 255.0)
    error = ((prediction - target) ** 2).sum(0)
    total = float(error.sum())
    return float(error[ground].sum()) / total if total > 0.0 else 0.0


def _write_report(report: Path, figure: Path, columns: str, captions: list[str], renderer: str, model_path, extra: dict,
                  scores: dict, weights_name: str, count: int, seconds: float, data: list[str]) -> None:
    lines = [
        f"# Evaluation: {renderer}",
        "",
        f"- model: {model_path or ('shipped' if renderer_entry(renderer).architecture else f'none ({renderer})')}"
        + (f", trained {extra.get('steps', '?')} steps" if extra.get("steps") else "")
        + (f", shading the {extra['shading_grid']} grid" if extra.get("shading_grid") else "")
        + (f" at the shader's {extra['shader_quality']} quality" if extra.get("shader_quality") else "")
        + (f" starting from {extra['init']} (trained {extra.get('init_steps', '?')} steps)" if extra.get("init") else "")
        + (f"; distilled to {distilled.get('post_light_blocks', '?')} residual block(s) after the light merge in "
           f"{distilled.get('steps', '?')} steps" if isinstance(distilled := extra.get("distilled"), dict) else ""),
        f"- data: {', '.join(map(str, data))}; {count} samples; {seconds:.1f} s on {platform.node() or 'this machine'}",
        f"- perceptual metric: VGG16 conv1 + 0.1 conv2 with {weights_name}",
        "",
        "| setting | samples | MSE (0-255) | DSSIM | perceptual | share of the MSE off the object |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for setting in sorted(scores):
        values = scores[setting]
        mean = {k: float(np.mean([v[k] for v in values])) for k in METRICS}
        ground = sum(v["ground_share"] * v["mse"] for v in values) / max(sum(v["mse"] for v in values), 1e-12)
        lines.append(f"| {setting} | {len(values)} | {mean['mse']:.2f} | {mean['dssim']:.4f} | {mean['perceptual']:.3f} "
                     f"| {100 * ground:.0f} % |")
    every = [v for values in scores.values() for v in values]
    if any(v["lighting"] != "area light" or v["material"] != "matte" or v["ground"] != "plain square" for v in every):
        for key in ("lighting", "material", "ground"):
            lines += ["", f"| {key} | samples | MSE (0-255) | DSSIM | perceptual |", "|---|---:|---:|---:|---:|"]
            for label in sorted({v[key] for v in every}):
                values = [v for v in every if v[key] == label]
                mean = {k: float(np.mean([v[k] for v in values])) for k in METRICS}
                lines.append(f"| {label} | {len(values)} | {mean['mse']:.2f} | {mean['dssim']:.4f} "
                             f"| {mean['perceptual']:.3f} |")
        if renderer_entry(renderer).architecture and not extra.get("environment_input"):
            lines += ["", "This network does not read environments or materials: for those samples it shows the "
                          "voxel shader's image, as the editor does."]
    lines += _object_count_table(every)
    lines += ["", f"![{columns}]({figure.name})", "", f"Figure rows ({columns}), top to bottom:", ""]
    lines += [f"{number}. {caption}" for number, caption in enumerate(captions, 1)]
    lines += [""] + _object_table(scores)
    with atomic_path(report) as tmp:
        tmp.write_text("\n".join(lines))


def _object_count_table(every: list[dict]) -> list[str]:
    """Lines of a table of the metrics by the number of objects in the scene, and the MSE inside each object's
    shadow on the others (renderer.shading.shadows_of_others), when some scene holds several objects."""
    if all(v["objects"] == 1 for v in every):
        return []
    lines = ["", "| objects in the scene | samples | MSE (0-255) | DSSIM | perceptual | MSE in the others' shadows "
                 "(pixels) |", "|---:|---:|---:|---:|---:|---:|"]
    for count in sorted({v["objects"] for v in every}):
        values = [v for v in every if v["objects"] == count]
        mean = {k: float(np.mean([v[k] for v in values])) for k in METRICS}
        pixels = sum(v.get("shadow_pixels", 0) for v in values)
        shadow = (f"{sum(v['shadow_squared'] * v['shadow_pixels'] for v in values) / pixels:.1f} ({pixels})"
                  if pixels else "-")
        lines.append(f"| {count} | {len(values)} | {mean['mse']:.2f} | {mean['dssim']:.4f} | {mean['perceptual']:.3f} "
                     f"| {shadow} |")
    return lines


def _object_table(scores: dict) -> list[str]:
    """Lines of a table of each object's mean MSE and DSSIM over its views, worst MSE first."""
    views: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for setting, values in scores.items():
        for v in values:
            views[(setting, v["object"])].append(v)
    means = {key: {k: float(np.mean([v[k] for v in vs])) for k in ("mse", "dssim")} for key, vs in views.items()}
    lines = ["## Per object (mean over its views, worst first)", "",
             "| object | setting | views | MSE (0-255) | DSSIM |", "|---|---|---:|---:|---:|"]
    for (setting, name), mean in sorted(means.items(), key=lambda item: -item[1]["mse"]):
        lines.append(f"| {name} | {setting} | {len(views[(setting, name)])} | {mean['mse']:.2f} | {mean['dssim']:.4f} |")
    return lines + [""]
