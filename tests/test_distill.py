"""Distillation: the cut student starts as the teacher without its later blocks, training brings it nearer the
teacher, the file it writes loads, and impossible values are refused."""

import numpy as np
import pytest
import torch

from app.cli import run
from models.networks.checkpoint import load_model, save_model
from models.networks.config import HalfResolutionRefinerConfig
from models.networks.nvr import build_model
from models.training.distill import DistillConfig, distill, student_of
from renderer.errors import InputError

TINY = HalfResolutionRefinerConfig(grid_size=16, output_size=32)


def random_teacher(seed: int = 0):
    """A tiny NVR+ with random weights and BatchNorm statistics (so no layer is an identity by chance)."""
    torch.manual_seed(seed)
    model = build_model("nvr_plus", TINY)
    for module in model.modules():
        if isinstance(module, torch.nn.BatchNorm2d):
            module.running_mean.uniform_(-0.1, 0.1)
            module.running_var.uniform_(0.5, 1.5)
            module.weight.data.uniform_(0.5, 1.5)
            module.bias.data.uniform_(-0.1, 0.1)
    for parameter in model.rerender.to_rgb.parameters():  # a new refiner's correction starts at zero
        parameter.data.normal_(0.0, 0.1)
    return model.eval()


def inputs(model, seed: int = 1):
    g, s = TINY.grid_size, TINY.output_size
    generator = torch.Generator().manual_seed(seed)
    voxels = torch.rand((2, 4, g, g, g), generator=generator)
    voxels[:, 3] = (voxels[:, 3] > 0.7).float()
    light = torch.tensor([[0.3, 0.6, -0.8], [-0.5, 0.9, -1.2]])
    splat = torch.rand((2, 3, s, s), generator=generator)
    shading = torch.rand((2, 13, s, s), generator=generator)
    return voxels, light, splat, shading


def test_student_keeps_every_other_weight_and_the_first_blocks():
    teacher = random_teacher()
    student = student_of(teacher, 1)
    assert student.config.post_light_blocks == 1
    assert student.config == HalfResolutionRefinerConfig(grid_size=16, output_size=32, post_light_blocks=1)
    ours, theirs = student.state_dict(), teacher.state_dict()
    assert set(theirs) - set(ours) == {k for k in theirs if k.startswith("light_decoder.blocks.blocks.1.")}
    for key, value in ours.items():
        assert torch.equal(value, theirs[key]), key


def test_cutting_a_block_that_adds_nothing_changes_nothing():
    # A residual block whose body ends in a BatchNorm with zero scale and shift passes its (non-negative, after the
    # ReLU before it) input through; without it the network computes the same image.
    teacher = random_teacher()
    last_norm = teacher.light_decoder.blocks.blocks[1].body[4]
    last_norm.weight.data.zero_()
    last_norm.bias.data.zero_()
    student = student_of(teacher, 1)
    other = random_teacher()
    with torch.no_grad():
        voxels, light, splat, shading = inputs(teacher)
        latent = teacher.encode_voxels(voxels)
        expected, got = teacher.light_decoder(latent, light), student.light_decoder(latent, light)
        image, student_image = (model(voxels, light, splat, shading=shading) for model in (teacher, student))
        # the same cut of a teacher whose second block does add something
        other_latent = other.encode_voxels(voxels)
        other_cut = student_of(other, 1).light_decoder(other_latent, light) - other.light_decoder(other_latent, light)
    assert torch.allclose(got, expected, atol=1e-6) and torch.allclose(student_image, image, atol=1e-6)
    assert other_cut.abs().max() > 1e-3


@pytest.fixture(scope="module")
def distilled(tmp_path_factory):
    folder = tmp_path_factory.mktemp("distill")
    teacher_path = folder / "teacher.safetensors"
    teacher = random_teacher()
    save_model(teacher_path, teacher, TINY, {"steps": "7"})
    config = DistillConfig(teacher=str(teacher_path), post_light_blocks=1, objects=2, views=3, steps=40, batch=4,
                           lr=3e-4, resolution=24, categories=("chair", "stool"))
    measured = distill(folder / "student.safetensors", config, progress=False)
    return folder / "student.safetensors", config, measured


def test_distillation_brings_the_student_nearer_the_teacher(distilled):
    _, _, measured = distilled
    assert measured["held_out_latents"] == 1  # six latents, every tenth held out
    assert 0.0 < measured["relative_error"] < 0.8 * measured["relative_error_start"]


@pytest.mark.parametrize("train_merge", [False, True])
def test_the_light_code_and_merge_learn_only_when_asked(distilled, tmp_path, train_merge):
    """With no block after the merge the student still learns (the decoder, and with train_merge the light code and
    the merge too); without train_merge those keep the teacher's weights, with it they move."""
    _, config, _ = distilled
    teacher = load_model(config.teacher)[0]
    student_config = DistillConfig(teacher=config.teacher, post_light_blocks=0, objects=2, views=3, steps=20, batch=4,
                                   resolution=24, categories=("stool",), train_merge=train_merge)
    measured = distill(tmp_path / "student.safetensors", student_config, progress=False)
    student, _, extra = load_model(tmp_path / "student.safetensors")
    assert extra["distilled"]["train_merge"] is train_merge
    assert measured["relative_error"] < measured["relative_error_start"]
    ours, theirs = student.state_dict(), teacher.state_dict()
    for prefix in ("light_decoder.merge.", "light_decoder.light_mlp."):
        moved = [not torch.equal(ours[k], theirs[k]) for k in ours if k.startswith(prefix) and ours[k].is_floating_point()]
        assert moved and any(moved) is train_merge, prefix
    assert torch.equal(ours["voxel_encoder.stages.0.0.weight"], theirs["voxel_encoder.stages.0.0.weight"])


def test_the_student_file_loads_and_says_what_it_was_distilled_from(distilled):
    path, config, measured = distilled
    model, loaded_config, extra = load_model(path)
    assert loaded_config.post_light_blocks == 1
    assert len(model.light_decoder.blocks.blocks) == 1
    assert extra["steps"] == "7"  # the teacher's training record is kept
    assert extra["distilled"]["teacher"] == config.teacher
    assert extra["distilled"]["relative_error"] == measured["relative_error"]
    voxels, light, splat, shading = inputs(model)
    with torch.no_grad():
        image = model(voxels, light, splat, shading=shading)
    assert np.isfinite(image.numpy()).all()


@pytest.mark.parametrize("change, message", [
    (dict(post_light_blocks=2), "--post-light-blocks must be from 0 to 1"),
    (dict(post_light_blocks=-1), "--post-light-blocks must be from 0 to 1"),
    (dict(steps=0), "--steps must be a whole number of at least 1"),
    (dict(objects=1, views=1), "at least 2"),
    (dict(lr=float("nan")), "--lr must be a positive number"),
    (dict(resolution=2), "--res must be from"),
    (dict(categories=("chair", "spoon")), "--categories must name object categories"),
    (dict(categories=()), "--categories must name object categories"),
])
def test_impossible_values_are_refused(change, message):
    with pytest.raises(InputError, match=message):
        DistillConfig(teacher="t.safetensors", **change).check(teacher_blocks=2)


def test_cli_refuses_a_teacher_that_is_not_a_weights_file(tmp_path, capsys):
    broken = tmp_path / "teacher.safetensors"
    broken.write_bytes(b"not a weights file")
    code = run(["distill", "--model", str(broken), "--out", str(tmp_path / "student.safetensors")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and "teacher.safetensors" in err
    assert not (tmp_path / "student.safetensors").exists()


def test_cli_writes_a_student_that_loads(distilled, tmp_path, capsys):
    _, config, _ = distilled
    out = tmp_path / "student.safetensors"
    code = run(["distill", "--model", config.teacher, "--out", str(out), "--objects", "2", "--views", "1",
                "--steps", "2", "--batch", "2", "--res", "24", "--categories", "stool"])
    assert code == 0
    assert f"wrote {out}" in capsys.readouterr().out
    assert load_model(out)[1].post_light_blocks == 1
    assert run(["distill", "--model", config.teacher, "--out", str(out)]) == 2  # exists: refused without --force
