"""Distillation: a trained NVR+ made faster by fewer residual blocks after the light merge.

A light edit reruns everything from the light merge on (models/engine/), and on a 2-core CPU without AVX512 the
96-channel residual blocks after the merge are a quarter of that. The student is the teacher with only the first
`post_light_blocks` of them; those blocks and the decoder after them (with `train_merge`, the light code and the
merge before them too) learn to give the teacher's decoder features for the same latent and light (mean squared
error), and every other layer keeps the teacher's weights. No rendered
images are needed: the latents are the teacher's voxel branch on procedurally generated training-split objects in
random training views (renderer/dataset.py's protocol), and every step draws new lights, so the student sees the
whole light box.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from models.training.config import DistillConfig
from renderer.errors import InputError

HELD_OUT_EVERY = 10  # every tenth latent is kept out of training and measures the student


def student_of(teacher, post_light_blocks: int):
    """The teacher's network with only its first `post_light_blocks` residual blocks after the light merge: every
    other weight copied, so it starts as the teacher with the later blocks cut out."""
    from models.networks.nvr import build_model

    config = dataclasses.replace(teacher.config, post_light_blocks=post_light_blocks)
    student = build_model(teacher.architecture, config)
    dropped = {f"light_decoder.blocks.blocks.{k}." for k in range(post_light_blocks, teacher.config.post_light_blocks)}
    state = {key: value for key, value in teacher.state_dict().items()
             if not any(key.startswith(prefix) for prefix in dropped)}
    student.load_state_dict(state)
    return student.eval()


def training_latents(teacher, config: DistillConfig, progress: bool = True) -> tuple[torch.Tensor, np.ndarray]:
    """The teacher's latents (N, C, s, s) of `config.objects` training-split objects (config.categories and the
    appearance settings in turn) in `config.views` random training views each, and each view's camera elevation (N,)."""
    from tqdm import tqdm

    from models.training.data import network_inputs
    from renderer.dataset import sample_train_views, view_scene
    from renderer.objects import SETTINGS, apply_appearance, generate_object, split_seeds
    from renderer.voxels import voxelize

    rng = np.random.default_rng(config.seed)
    seeds = split_seeds("train", config.objects)
    latents, elevations = [], []
    for index in tqdm(range(config.objects), disable=not progress, unit="object", desc="latents"):
        setting = SETTINGS[index % len(SETTINGS)]
        labeled = generate_object(config.categories[index % len(config.categories)], int(seeds[index]))
        mesh, floor_color, appearance = apply_appearance(labeled, setting, int(rng.integers(2**31)), "train")
        floor_color = tuple(float(c) for c in floor_color)
        rgba = voxelize(mesh, resolution=config.resolution)
        if setting == "single":  # as the data sets color single-colored objects
            rgba[..., :3] = np.where(rgba[..., 3:] > 0.5, np.asarray(appearance["color"], dtype=np.float32), 0.0)
        grids = []
        for view in sample_train_views(rng, config.views):
            scene = view_scene(view, "object.npz", floor_color, teacher.config.output_size)
            grids.append(network_inputs(scene, [rgba], floor_color, teacher.config.grid_size)[0])
            elevations.append(view.elevation_deg)
        with torch.no_grad():
            latents.append(teacher.encode_voxels(torch.stack(grids)))
    return torch.cat(latents), np.asarray(elevations)


def network_lights(rng: np.random.Generator, elevations: np.ndarray) -> torch.Tensor:
    """A light drawn uniformly over the training range per elevation, as the network's input (N, 3)."""
    from models.networks.nvr import light_to_network
    from renderer.dataset import sample_light

    return torch.from_numpy(np.stack([light_to_network(np.asarray(sample_light(rng)), float(e)) for e in elevations]))


def relative_error(student, teacher, batches: list[tuple[torch.Tensor, torch.Tensor]]) -> float:
    """The student's squared error in the teacher's decoder features over their variance per channel (0: equal)."""
    error = variance = 0.0
    with torch.no_grad():
        for latent, light in batches:
            target = teacher.light_decoder(latent, light)
            error += (student.light_decoder(latent, light) - target).pow(2).sum().item()
            variance += (target - target.mean(dim=(0, 2, 3), keepdim=True)).pow(2).sum().item()
    return error / max(variance, 1e-30)


def distill(out: str | Path, config: DistillConfig, progress: bool = True) -> dict[str, Any]:
    """Distil config.teacher into a network with config.post_light_blocks blocks after the light merge, written to
    `out`; returns what was measured (the held-out relative error before and after)."""
    from tqdm import tqdm

    from models.networks.checkpoint import load_model, save_model
    from models.networks.nvr import NVRPlus

    teacher, teacher_config, teacher_extra = load_model(config.teacher)
    if not isinstance(teacher, NVRPlus):
        raise InputError("is not an NVR+ network (distillation keeps NVR+'s other branches)", config.teacher)
    if teacher_config.environment_input:  # its lights are drawn as area lights alone
        raise InputError("reads the environment; distillation draws area lights only", config.teacher)
    config.check(teacher_config.post_light_blocks)
    latents, elevations = training_latents(teacher, config, progress)
    held_out = np.arange(len(latents)) % HELD_OUT_EVERY == 0
    train_rows, test_rows = np.flatnonzero(~held_out), np.flatnonzero(held_out)
    test_rng = np.random.default_rng([config.seed, 1])
    test_batches = [(latents[rows], network_lights(test_rng, elevations[rows]))
                    for rows in np.array_split(test_rows, max(1, math.ceil(len(test_rows) / config.batch)))]

    student = student_of(teacher, config.post_light_blocks)
    decoder = student.light_decoder
    trained = [*decoder.blocks.parameters(), *decoder.decoder.parameters()]
    if config.train_merge:
        trained += [*decoder.light_mlp.parameters(), *decoder.merge.parameters()]
    student.requires_grad_(False)
    for parameter in trained:
        parameter.requires_grad_(True)
    # eval mode throughout: BatchNorm keeps the teacher's statistics (an affine map the inference copy folds away)
    optimizer = torch.optim.Adam(trained, lr=config.lr)
    before = relative_error(student, teacher, test_batches)
    rng = np.random.default_rng([config.seed, 2])
    bar = tqdm(range(config.steps), disable=not progress, unit="step", desc="distil")
    for step in bar:
        for group in optimizer.param_groups:
            group["lr"] = config.lr * 0.5 * (1.0 + math.cos(math.pi * step / config.steps))
        rows = train_rows[rng.integers(len(train_rows), size=config.batch)]
        latent, light = latents[rows], network_lights(rng, elevations[rows])
        with torch.no_grad():
            target = teacher.light_decoder(latent, light)
        loss = F.mse_loss(student.light_decoder(latent, light), target)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        bar.set_postfix(loss=f"{loss.item():.4f}")
    after = relative_error(student, teacher, test_batches)
    measured = {"held_out_latents": len(test_rows), "relative_error_start": round(before, 5),
                "relative_error": round(after, 5)}
    extra = {**teacher_extra, "distilled": {**dataclasses.asdict(config), **measured}}
    save_model(out, student, student.config, extra)
    return measured
