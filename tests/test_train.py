"""Training: the loss falls, a resumed run equals an uninterrupted one, DDP equals one process."""

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import load_file

from models.engine.onednn import cpu_can_run_bfloat16
from models.networks.checkpoint import load_model
from models.training.data import VoxelRenderSet
from models.training.train import CHECKPOINT, TrainConfig, batch_indices, train
from renderer.errors import InputError
from tests.fake_data import make_fake_dataset

TINY = (("grid_size", 16), ("output_size", 32))
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    return make_fake_dataset(tmp_path_factory.mktemp("data") / "set", samples=4)


def config(data: Path, **changes) -> TrainConfig:
    base = dict(data=(str(data),), steps=4, batch=2, threads=1, config_overrides=TINY, perceptual_crop=0, log_every=1,
                loader_workers=0)
    base.update(changes)
    return TrainConfig(**base)


def weights(path: Path) -> dict[str, torch.Tensor]:
    return load_file(str(path))


def test_a_few_steps_lower_the_loss(data, tmp_path):
    train(tmp_path / "run", config(data, steps=30, batch=4, lr=3e-3), progress=False)
    lines = (tmp_path / "run" / "log.csv").read_text().splitlines()[1:]
    losses = [float(line.split(",")[1]) for line in lines]
    assert len(losses) == 30
    assert sum(losses[-5:]) / 5 < 0.8 * sum(losses[:5]) / 5


@pytest.mark.skipif(not cpu_can_run_bfloat16(), reason="this CPU cannot run bfloat16 convolutions")
def test_a_bf16_run_starts_at_the_fp32_loss_lowers_it_and_keeps_fp32_weights(data, tmp_path):
    train(tmp_path / "fp32", config(data, steps=1, batch=4), progress=False)
    train(tmp_path / "bf16", config(data, steps=30, batch=4, lr=3e-3, precision="bf16"), progress=False)
    first = float((tmp_path / "fp32" / "log.csv").read_text().splitlines()[1].split(",")[1])
    losses = [float(line.split(",")[1]) for line in (tmp_path / "bf16" / "log.csv").read_text().splitlines()[1:]]
    assert losses[0] != first  # the forward pass did run in bfloat16
    assert losses[0] == pytest.approx(first, rel=0.02)  # bfloat16 keeps 8 bits of mantissa: about 0.4 % a value
    assert sum(losses[-5:]) / 5 < 0.8 * sum(losses[:5]) / 5
    stored = weights(tmp_path / "bf16" / CHECKPOINT)
    assert all(v.dtype == torch.float32 for v in stored.values() if v.is_floating_point())


def test_resumed_run_equals_uninterrupted_run(data, tmp_path):
    train(tmp_path / "whole", config(data, steps=4), progress=False)
    train(tmp_path / "parts", config(data, steps=2), progress=False)
    train(tmp_path / "parts", config(data, steps=4), resume=True, progress=False)
    a, b = weights(tmp_path / "whole" / CHECKPOINT), weights(tmp_path / "parts" / CHECKPOINT)
    assert a.keys() == b.keys()
    for key in a:
        assert torch.equal(a[key], b[key]), key


def test_a_run_killed_after_its_checkpoint_logs_each_step_once_when_resumed(data, tmp_path):
    train(tmp_path / "whole", config(data, steps=4), progress=False)
    train(tmp_path / "parts", config(data, steps=2), progress=False)  # its checkpoint holds step 2
    log = tmp_path / "parts" / "log.csv"
    log.write_text(log.read_text() + "2,9.0,9.0,0.0,1.0,9.0\n")  # logged by a run killed before its next checkpoint
    train(tmp_path / "parts", config(data, steps=4), resume=True, progress=False)
    steps_losses = [line.split(",")[:2] for line in log.read_text().splitlines()[1:]]
    whole = [line.split(",")[:2] for line in (tmp_path / "whole" / "log.csv").read_text().splitlines()[1:]]
    assert steps_losses == whole


def test_the_log_records_the_squared_error_and_a_resumed_old_log_keeps_its_columns(data, tmp_path):
    train(tmp_path / "run", config(data, steps=2, mse_weight=5.0), progress=False)
    header, *rows = (tmp_path / "run" / "log.csv").read_text().splitlines()
    assert header == "step,loss,l1,perceptual,seconds,mse" and len(rows) == 2
    step, loss, l1, _, _, mse = (float(v) for v in rows[0].split(","))
    assert step == 0 and 0.0 < mse < l1 and loss >= l1 + 5.0 * mse - 1e-5  # the perceptual term is >= 0
    log = tmp_path / "run" / "log.csv"  # a log written before the "mse" column existed
    log.write_text("step,loss,l1,perceptual,seconds\n" + "\n".join(",".join(r.split(",")[:5]) for r in rows) + "\n")
    train(tmp_path / "run", config(data, steps=4, mse_weight=5.0), resume=True, progress=False)
    lines = log.read_text().splitlines()
    assert lines[0] == "step,loss,l1,perceptual,seconds" and len(lines) == 5
    assert all(len(line.split(",")) == 5 for line in lines)


def _with_colors_reordered(source: Path, out: Path, order: list[int]) -> None:
    """A copy of a fake data set in which every color of every scene has its channels reordered: the object's
    voxels, the floor, and (each a function of the scene's colors, channel by channel) its splat and target."""
    import json
    import shutil

    from renderer.io import load_image, save_png
    from renderer.voxels import load_voxels, save_voxels

    shutil.copytree(source, out)
    rgba = load_voxels(out / "objects/o00000.npz")
    save_voxels(out / "objects/o00000.npz", np.concatenate([rgba[..., order], rgba[..., 3:]], axis=-1))
    manifest = json.loads((out / "manifest.json").read_text())
    for sample in manifest["samples"]:
        floor = sample["scene"]["floor"]
        floor["color"] = [floor["color"][c] for c in order]
        for key in ("splat", "target"):
            save_png(out / sample[key], load_image(out / sample[key])[0][..., order])
    (out / "manifest.json").write_text(json.dumps(manifest))


def test_a_color_permuted_sample_is_the_sample_of_the_scene_with_its_colors_permuted(data, tmp_path):
    """Light and sky are white, so the grid, the splat, the lit floor, the shader's image and buffers and the target of a scene
    whose colors all have their channels reordered are the originals' with those channels reordered."""
    from models.training.data import permute_colors

    order = [2, 0, 1]
    _with_colors_reordered(data, tmp_path / "permuted", order)
    plain = VoxelRenderSet([data], grid_size=16, shading=True, floor_light=True)
    permuted = VoxelRenderSet([tmp_path / "permuted"], grid_size=16, shading=True, floor_light=True)
    for index in range(len(plain)):
        batch = {key: value[None] for key, value in plain[index].items() if key != "index"}
        got = permute_colors(batch, torch.tensor([order]))
        expected = permuted[index]
        for key in got:
            assert torch.allclose(got[key][0], expected[key], atol=2e-5), (index, key)
        assert not torch.equal(got["shading"], batch["shading"])  # the colors did move


def test_color_orders_are_permutations_fixed_by_seed_and_step():
    from models.training.data import color_orders

    a = color_orders(3, 17, 60)
    assert torch.equal(a, color_orders(3, 17, 60)) and not torch.equal(a, color_orders(3, 18, 60))
    assert all(sorted(row.tolist()) == [0, 1, 2] for row in a)
    assert len({tuple(row.tolist()) for row in a}) == 6  # 60 draws of six orders meet them all


def test_a_run_with_color_permutation_resumes_as_it_would_have_run(data, tmp_path):
    train(tmp_path / "whole", config(data, steps=4, color_permutation=True), progress=False)
    train(tmp_path / "parts", config(data, steps=2, color_permutation=True), progress=False)
    train(tmp_path / "parts", config(data, steps=4, color_permutation=True), resume=True, progress=False)
    a, b = weights(tmp_path / "whole" / CHECKPOINT), weights(tmp_path / "parts" / CHECKPOINT)
    assert all(torch.equal(a[key], b[key]) for key in a)
    plain = weights(train(tmp_path / "plain", config(data, steps=4), progress=False).parent / CHECKPOINT)
    assert not all(torch.equal(a[key], plain[key]) for key in a)  # the permutation changed what was learned


def test_existing_run_is_not_overwritten_without_resume(data, tmp_path):
    train(tmp_path / "run", config(data, steps=1), progress=False)
    with pytest.raises(InputError, match="--resume"):
        train(tmp_path / "run", config(data, steps=1), progress=False)


def test_batches_are_fixed_by_seed_and_step():
    assert torch.equal(batch_indices(3, 10, 8, 100), batch_indices(3, 10, 8, 100))
    assert not torch.equal(batch_indices(3, 10, 8, 100), batch_indices(3, 11, 8, 100))
    assert not torch.equal(batch_indices(3, 10, 8, 100), batch_indices(4, 10, 8, 100))


def test_each_epoch_reads_every_sample_once():
    # 7 samples in batches of 3: steps 0-6 hold 21 positions, three whole epochs (a batch straddles two of them).
    positions = torch.cat([batch_indices(5, step, 3, 7) for step in range(7)])
    for epoch in range(3):
        assert sorted(positions[7 * epoch:7 * epoch + 7].tolist()) == list(range(7))
    assert positions[:7].tolist() != positions[7:14].tolist()  # each epoch in another order


def test_a_run_resumed_on_other_data_starts_its_first_epoch_there(data, tmp_path):
    from safetensors import safe_open

    def epochs(run: Path) -> tuple[int, dict]:
        with safe_open(str(run / CHECKPOINT), framework="pt") as f:
            metadata = f.metadata()
        return int(metadata["epoch_origin"]), json.loads(metadata["epoch_data"])

    more = make_fake_dataset(tmp_path / "more", samples=3)
    train(tmp_path / "run", config(data, steps=3), progress=False)
    assert epochs(tmp_path / "run") == (0, {"data": [str(data)], "samples": 4})
    train(tmp_path / "run", config(data, steps=5), resume=True, progress=False)  # the same data: its epochs go on
    assert epochs(tmp_path / "run")[0] == 0
    both = replace(config(data, steps=7), data=(str(data), str(more)))
    train(tmp_path / "run", both, resume=True, progress=False)
    assert epochs(tmp_path / "run") == (5, {"data": [str(data), str(more)], "samples": 7})
    # From that step on, the first ceil(7 / 2) steps read each of the 7 samples once.
    read = torch.cat([batch_indices(0, step, 2, 7, origin=5) for step in range(5, 9)])[:7]
    assert sorted(read.tolist()) == list(range(7))


@pytest.mark.skipif(not torch.distributed.is_available(), reason="torch without distributed support")
def test_two_process_ddp_matches_one_process_with_the_same_total_batch(data, tmp_path):
    train(tmp_path / "single", config(data, steps=3, batch=4), progress=False)
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    command = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
               "-m", "app.cli", "train", "--data", str(data), "--out", str(tmp_path / "ddp"), "--steps", "3",
               "--batch", "4", "--threads", "1", "--perceptual-crop", "0", "--precision", "fp32",
               "--set", "grid_size=16", "--set", "output_size=32"]
    result = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    train(tmp_path / "start", config(data, steps=0, batch=4), progress=False)
    start, a, b = (weights(tmp_path / name / CHECKPOINT) for name in ("start", "single", "ddp"))
    keys = [k for k in a if k.startswith("model.") and a[k].is_floating_point()]
    step_single = torch.cat([(a[k] - start[k]).flatten().double() for k in keys])
    step_ddp = torch.cat([(b[k] - start[k]).flatten().double() for k in keys])
    # Same updates up to float rounding: the BatchNorm statistics and gradients cover the global batch.
    # (Adam turns rounding noise in gradients that are zero in theory into full-size steps, so compare norms.)
    assert float((step_single - step_ddp).norm() / step_single.norm()) < 0.01  # per-rank BatchNorm gives ~0.04


def test_init_from_a_model_without_the_lit_floor_starts_out_computing_the_same_images(tmp_path):
    from models.networks.checkpoint import save_model
    from models.networks.config import CompactConfig
    from models.networks.nvr import build_model
    from models.training.train import initialize_from

    old_config = CompactConfig(grid_size=16, output_size=32, floor_light_input=False)
    torch.manual_seed(3)
    old = build_model("nvr_plus", old_config).eval()
    save_model(tmp_path / "old.safetensors", old, old_config)
    torch.manual_seed(4)
    new = build_model("nvr_plus", CompactConfig(grid_size=16, output_size=32)).eval()
    initialize_from(new, tmp_path / "old.safetensors")
    voxels = (torch.rand(2, 4, 16, 16, 16) > 0.8).float()
    light, splat, floor_light = torch.randn(2, 3), torch.rand(2, 3, 32, 32), torch.rand(2, 3, 32, 32)
    with torch.no_grad():
        assert torch.equal(new(voxels, light, splat, floor_light), old(voxels, light, splat))
    # The new input channels start at zero but are trainable: they are not frozen.
    first = new.splat_encoder.layers[0][0].weight
    assert first.requires_grad and torch.count_nonzero(first[:, 3:]) == 0 and torch.count_nonzero(first[:, :3]) > 0

    with pytest.raises(InputError, match="holds a nvr network"):  # NVR+ cannot start from NVR
        save_model(tmp_path / "nvr.safetensors", build_model("nvr", old_config), old_config)
        initialize_from(new, tmp_path / "nvr.safetensors")
    wider = CompactConfig(grid_size=16, output_size=32, latent_channels=48)
    save_model(tmp_path / "wider.safetensors", build_model("nvr_plus", wider), wider)
    with pytest.raises(InputError, match="has shape"):
        initialize_from(new, tmp_path / "wider.safetensors")


def test_nvr_started_from_nvr_plus_takes_its_voxel_and_light_branches_and_keeps_its_own_output_layer(tmp_path):
    from models.networks.checkpoint import save_model
    from models.networks.config import CompactConfig
    from models.networks.nvr import build_model
    from models.training.train import initialize_from

    config = CompactConfig(grid_size=16, output_size=32)
    torch.manual_seed(5)
    plus = build_model("nvr_plus", config).eval()
    save_model(tmp_path / "plus.safetensors", plus, config)
    torch.manual_seed(6)
    nvr = build_model("nvr", config).eval()
    fresh_output = {k: v.clone() for k, v in nvr.to_rgb.state_dict().items()}
    initialize_from(nvr, tmp_path / "plus.safetensors")
    voxels, light = (torch.rand(1, 4, 16, 16, 16) > 0.8).float(), torch.randn(1, 3)
    with torch.no_grad():  # same latent and light features as the NVR+ it came from
        latent = nvr.encode_voxels(voxels)
        assert torch.equal(latent, plus.encode_voxels(voxels))
        assert torch.equal(nvr._features(latent, light), plus._features(latent, light))
    assert all(torch.equal(v, fresh_output[k]) for k, v in nvr.to_rgb.state_dict().items())


def test_a_run_started_from_other_weights_records_them_and_their_steps(data, tmp_path):
    from models.networks.checkpoint import load_model, save_model
    from models.networks.config import CompactConfig
    from models.networks.nvr import build_model

    old_config = CompactConfig(grid_size=16, output_size=32, floor_light_input=False)
    save_model(tmp_path / "old.safetensors", build_model("nvr_plus", old_config), old_config, {"steps": "77"})
    final = train(tmp_path / "run", config(data, steps=1, init=str(tmp_path / "old.safetensors")), progress=False)
    _, _, extra = load_model(final)
    assert extra["init"] == str(tmp_path / "old.safetensors") and extra["init_steps"] == "77"
    # A run from that run's model counts both: its 1 step and the 77 behind its start.
    again = train(tmp_path / "again", config(data, steps=1, init=str(final)), progress=False)
    assert load_model(again)[2]["init_steps"] == "78"
    # Resumed later, without --init, after the file it started from was overwritten: the start is as it was.
    save_model(tmp_path / "old.safetensors", build_model("nvr_plus", old_config), old_config, {"steps": "5"})
    resumed = train(tmp_path / "run", config(data, steps=2), resume=True, progress=False)
    assert {k: load_model(resumed)[2][k] for k in ("init", "init_steps")} == {"init": str(tmp_path / "old.safetensors"),
                                                                              "init_steps": "77"}


def test_learning_rate_is_constant_then_falls_linearly_over_the_last_steps():
    from models.training.train import TrainConfig, learning_rate

    constant = TrainConfig(data=("d",), steps=10, lr=1e-3)
    assert [learning_rate(constant, step) for step in (0, 5, 9)] == [1e-3, 1e-3, 1e-3]
    falling = TrainConfig(data=("d",), steps=10, lr=1e-3, lr_decay_steps=4, lr_final_fraction=0.2)
    # Steps 6..9 fall by (1 - 0.2) / 4 = 0.2 of lr each, reaching 0.2 * lr on the last step.
    expected = [1e-3] * 6 + [8e-4, 6e-4, 4e-4, 2e-4]
    assert [learning_rate(falling, step) for step in range(10)] == pytest.approx(expected)
    longer_than_run = TrainConfig(data=("d",), steps=2, lr=1.0, lr_decay_steps=5, lr_final_fraction=0.0)
    assert [learning_rate(longer_than_run, step) for step in range(2)] == pytest.approx([0.5, 0.0])


def test_the_training_loop_uses_the_decayed_rate(data, tmp_path):
    # A rate falling to zero on the last step makes that step move no weight: the parameters equal
    # those of a run that stopped one step earlier (BatchNorm statistics still move, so they are left out).
    decayed = train(tmp_path / "decayed", config(data, steps=3, lr_decay_steps=1, lr_final_fraction=0.0), progress=False)
    shorter = train(tmp_path / "shorter", config(data, steps=2), progress=False)
    a, b = weights(decayed), weights(shorter)
    parameters = [k for k in a if not k.endswith(("running_mean", "running_var", "num_batches_tracked"))]
    assert parameters and all(torch.equal(a[k], b[k]) for k in parameters)
    moved = train(tmp_path / "moved", config(data, steps=3), progress=False)
    assert not all(torch.equal(weights(moved)[k], b[k]) for k in parameters)


@pytest.mark.parametrize("name", ["shader_refiner", "half_res_refiner"])
def test_a_shader_refiner_trains_from_the_shaded_image(data, tmp_path, name):
    # Its first loss is the shaded image's own error; training lowers it (the fake targets are no
    # physical images, so the correction has much to learn).
    train(tmp_path / "run", config(data, config=name, steps=20, batch=4, lr=3e-3), progress=False)
    losses = [float(line.split(",")[1]) for line in (tmp_path / "run" / "log.csv").read_text().splitlines()[1:]]
    assert sum(losses[-5:]) / 5 < 0.9 * sum(losses[:5]) / 5
    model, net_config, _ = load_model(tmp_path / "run" / "model.safetensors")
    assert net_config.shading_input and net_config.name == name


@pytest.mark.parametrize("factor", [1, 2])
def test_a_samples_shader_buffers_come_from_the_grid_the_config_names(data, factor):
    from renderer.shading import network_buffers, shade_scene
    from renderer.voxels import load_voxels

    dataset = VoxelRenderSet([data], grid_size=16, shading=True, shading_grid_factor=factor)
    scene = dataset.scene(1)
    # The network's input: the shaded image without the floor's reflection of the object (the network draws its own).
    expected = network_buffers(shade_scene(scene, load_voxels(scene.voxels_path()), scene.floor.color, 32, 16 * factor,
                                           reflection=False))
    np.testing.assert_allclose(dataset[1]["shading"].numpy().transpose(1, 2, 0), expected, rtol=0, atol=1e-6)
    assert dataset[1]["voxels"].shape[-1] == 16  # the network's own grid is unchanged


def test_a_shader_refiner_started_from_a_compact_nvr_plus_still_renders_the_shaded_image(tmp_path):
    from models.networks.checkpoint import save_model
    from models.networks.config import CompactConfig, ShaderRefinerConfig
    from models.networks.nvr import build_model
    from models.training.train import initialize_from

    torch.manual_seed(0)
    source = build_model("nvr_plus", CompactConfig(grid_size=16, output_size=32)).eval()
    save_model(tmp_path / "compact.safetensors", source, source.config)
    model = build_model("nvr_plus", ShaderRefinerConfig(grid_size=16, output_size=32)).eval()
    initialize_from(model, tmp_path / "compact.safetensors")
    torch.testing.assert_close(model.voxel_encoder.state_dict(), source.voxel_encoder.state_dict())
    voxels, light = torch.rand(1, 4, 16, 16, 16), torch.rand(1, 3)
    splat, shading = torch.rand(1, 3, 32, 32), torch.rand(1, 13, 32, 32)
    with torch.no_grad():
        torch.testing.assert_close(model(voxels, light, splat, None, shading), shading[:, :3])


def test_a_half_resolution_refiner_starts_from_a_full_resolution_one(tmp_path):
    from models.networks.checkpoint import save_model
    from models.networks.config import HalfResolutionRefinerConfig, ShaderRefinerConfig
    from models.networks.nvr import build_model
    from models.training.train import initialize_from

    torch.manual_seed(0)
    source = build_model("nvr_plus", ShaderRefinerConfig(grid_size=16, output_size=32)).eval()
    for parameter in source.parameters():  # trained-looking: no layer left at its initial value
        torch.nn.init.normal_(parameter, std=0.1)
    save_model(tmp_path / "full.safetensors", source, source.config)
    model = build_model("nvr_plus", HalfResolutionRefinerConfig(grid_size=16, output_size=32)).eval()
    initialize_from(model, tmp_path / "full.safetensors")
    old, new = source.state_dict(), model.state_dict()
    shared = [k for k in new if not k.startswith("to_features.0.")]
    assert all(torch.equal(new[k], old[k]) for k in shared)
    assert len(old) - len(new) == sum(k.startswith(("light_decoder.decoder.4.", "light_decoder.decoder.5."))
                                      for k in old) > 0  # the decoder's last doubling is left out
    assert new["to_features.0.weight"].shape[1] == 16 and not new["to_features.0.weight"].any()
    # So at step 0 it corrects from the splat branch alone: neither the voxels nor the light change its image.
    splat, shading = torch.rand(1, 3, 32, 32), torch.rand(1, 13, 32, 32)
    with torch.no_grad():
        a = model(torch.rand(1, 4, 16, 16, 16), torch.rand(1, 3), splat, None, shading)
        b = model(torch.rand(1, 4, 16, 16, 16), torch.rand(1, 3), splat, None, shading)
    torch.testing.assert_close(a, b, rtol=0, atol=0)
    assert (a - shading[:, :3]).abs().max() > 1e-3


def test_a_frozen_voxel_branch_keeps_its_weights_and_statistics(data, tmp_path):
    from models.networks.checkpoint import save_model
    from models.networks.config import CompactConfig
    from models.networks.nvr import build_model

    torch.manual_seed(0)
    start = build_model("nvr_plus", CompactConfig(grid_size=16, output_size=32))
    save_model(tmp_path / "start.safetensors", start, start.config)
    final = train(tmp_path / "run", config(data, steps=3, init=str(tmp_path / "start.safetensors"),
                                           freeze_voxel_branch=True), progress=False)
    before, after = start.state_dict(), weights(final)
    voxel = [k for k in before if k.startswith("voxel_encoder.") and not k.endswith("num_batches_tracked")]
    assert any(k.endswith("running_mean") for k in voxel)  # BatchNorm statistics are among what stays
    assert all(torch.equal(after[k], before[k]) for k in voxel)
    assert not torch.equal(after["light_decoder.merge.0.weight"], before["light_decoder.merge.0.weight"])
    with pytest.raises(InputError, match="freeze-voxel-branch"):  # its Adam state has no moments for the branch
        train(tmp_path / "run", config(data, steps=4), resume=True, progress=False)
    train(tmp_path / "run", config(data, steps=4, freeze_voxel_branch=True), resume=True, progress=False)


@pytest.mark.parametrize("option, value, named", [
    ("--lr", "inf", "--lr"), ("--lr", "1e30", "--lr"), ("--lr", "nan", "--lr"), ("--lr", "0", "--lr"),
    ("--steps", "-1", "--steps"), ("--batch", "-3", "--batch"), ("--threads", "-1", "--threads"),
    ("--device", "quantum", "--device"), ("--perceptual-crop", "-5", "--perceptual-crop"),
    ("--perceptual-crop", "7", "--perceptual-crop"), ("--seed", "-1", "--seed"),
    ("--lr-final-fraction", "2", "--lr-final-fraction"), ("--checkpoint-minutes", "0", "--checkpoint-minutes"),
    ("--mse-weight", "-1", "--mse-weight"), ("--mse-weight", "nan", "--mse-weight"),
])
def test_impossible_training_options_are_one_line_refusals(data, tmp_path, capsys, option, value, named):
    from app.cli import run

    out = tmp_path / "run"
    code = run(["train", "--data", str(data), "--out", str(out), option, value])
    assert code == 2 and not out.exists()  # refused before anything was written or built
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and named in lines[0], lines


def test_training_option_refusals_name_the_option_and_its_limits():
    with pytest.raises(InputError, match=r"--lr must be a number above 0 and at most 1\.0, got inf"):
        TrainConfig(data=("d",), lr=float("inf"))
    with pytest.raises(InputError, match=r"--threads must be from 0 .* to 1024, got -1"):
        TrainConfig(data=("d",), threads=-1)
    with pytest.raises(InputError, match=r"--precision must be fp32 or bf16, got 'fp16'"):
        TrainConfig(data=("d",), precision="fp16")


# --- refusals before anything is written, and a kill during a checkpoint write ----------------------------


def test_a_network_too_large_to_build_is_refused_before_the_run_folder_exists(data, tmp_path):
    with pytest.raises(InputError, match=r"network of [\d,]+ parameters \(at most"):
        train(tmp_path / "run", config(data, config_overrides=TINY + (("latent_channels", 1_000_000),)), progress=False)
    assert not (tmp_path / "run").exists()


def test_data_of_another_image_size_is_refused_before_the_run_folder_exists(tmp_path):
    larger = make_fake_dataset(tmp_path / "set", samples=2, size=64)  # the TINY network renders 32 x 32
    with pytest.raises(InputError, match="is 64x64; the network renders 32x32"):
        train(tmp_path / "run", config(larger), progress=False)
    assert not (tmp_path / "run").exists()


def test_missing_loss_weights_or_init_file_leave_no_run_folder_and_the_same_command_then_runs(data, tmp_path):
    """Found on a lent GPU machine without the perceptual weights: the refused run had written run.json, so the
    same command, run again once the weights were there, was told the folder held a run to --resume."""
    missing = str(tmp_path / "absent.safetensors")
    with pytest.raises(InputError, match="absent.safetensors: file not found"):
        train(tmp_path / "run", config(data, steps=1, perceptual_weights=missing), progress=False)
    assert not (tmp_path / "run").exists()
    with pytest.raises(InputError, match="absent.safetensors"):
        train(tmp_path / "run", config(data, steps=1, init=missing), progress=False)
    assert not (tmp_path / "run").exists()
    train(tmp_path / "run", config(data, steps=1), progress=False)
    assert (tmp_path / "run" / "run.json").exists()


def test_a_broken_sample_is_refused_by_name_before_training(tmp_path):
    broken = make_fake_dataset(tmp_path / "set", samples=3)
    (broken / "images" / "s1.png").write_bytes(b"\x89PNG\r\n\x1a\n cut here")
    with pytest.raises(InputError, match=r"s1.png: sample s1: its target image is missing or unreadable"):
        train(tmp_path / "run", config(broken), progress=False)
    assert not (tmp_path / "run").exists()


KILLED_DURING_THIRD_CHECKPOINT = """
import importlib, os, signal, sys
from models.training.train import TrainConfig, train

train_module = importlib.import_module("models.training.train")  # the module (the package exports the function)

calls = 0
real_save = train_module.save_file

def save_and_die_on_the_third(tensors, filename, metadata=None):
    global calls
    calls += 1
    if calls < 3:
        return real_save(tensors, filename, metadata=metadata)
    real_save(tensors, filename, metadata=metadata)
    with open(filename, "r+b") as f:
        f.truncate(os.path.getsize(filename) // 2)  # half of the file is on disk
    os.kill(os.getpid(), signal.SIGKILL)

train_module.save_file = save_and_die_on_the_third
config = TrainConfig(data=(sys.argv[1],), steps=4, batch=2, threads=1, perceptual_crop=0, log_every=1, loader_workers=0,
                     checkpoint_minutes=1e-9, config_overrides=(("grid_size", 16), ("output_size", 32)))
train(sys.argv[2], config, progress=False)
"""


def test_a_run_killed_during_a_checkpoint_write_resumes_from_the_last_good_one(data, tmp_path):
    run = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    killed = subprocess.run([sys.executable, "-c", KILLED_DURING_THIRD_CHECKPOINT, str(data), str(run)], env=env,
                            capture_output=True, timeout=300)
    assert killed.returncode == -9  # SIGKILL, mid-write of the third checkpoint (after step 3)
    leftovers = [p for p in run.iterdir() if p.name.startswith(f".{CHECKPOINT}.")]
    assert len(leftovers) == 1  # the half-written temporary; the real name still holds checkpoint 2
    from safetensors import safe_open

    with safe_open(str(run / CHECKPOINT), framework="pt") as f:
        assert f.metadata()["step"] == "2"
    train(run, config(data, steps=4, checkpoint_minutes=1e-9), resume=True, progress=False)
    assert not [p for p in run.iterdir() if p.name.startswith(f".{CHECKPOINT}.")]  # cleaned up
    train(tmp_path / "whole", config(data, steps=4), progress=False)
    a, b = weights(tmp_path / "whole" / CHECKPOINT), weights(run / CHECKPOINT)
    assert a.keys() == b.keys() and all(torch.equal(a[key], b[key]) for key in a)


def test_the_thread_count_holds_after_a_compiled_shader_kernel():
    """numba's OpenMP layer would set OpenMP's count back to every core, and torch follows it."""
    import numba

    from models.threads import set_threads
    from renderer.shading import geometry as geometry_stage

    before = torch.get_num_threads(), numba.get_num_threads()
    try:
        set_threads(1)
        geometry_stage.distance_to_occupied(np.zeros((6, 6, 6), dtype=bool))
        assert torch.get_num_threads() == 1 and numba.get_num_threads() == 1
    finally:
        torch.set_num_threads(before[0])
        numba.set_num_threads(before[1])


def test_the_thread_count_holds_when_set_before_numbas_pool_has_started():
    """A fresh process (numba's pool not yet started) whose torch count was changed once: the pool's start
    must not undo set_threads (it did, and a resumed run then differed from an uninterrupted one)."""
    script = ("import torch, numba; torch.get_num_threads(); torch.set_num_threads(1); torch.set_num_threads(2); "
              "from models.threads import set_threads; set_threads(1); "
              "print(torch.get_num_threads(), numba.get_num_threads())")
    result = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["1", "1"]


def test_set_threads_runs_numpys_blas_on_one_thread():
    """OpenBLAS's idle workers poll between products: with two of them a light edit took 65 ms instead of 39."""
    script = ("import json, numpy; from threadpoolctl import threadpool_info, threadpool_limits; "
              "threadpool_limits(2, 'blas'); blas = lambda: [i['num_threads'] for i in threadpool_info() "
              "if i['user_api'] == 'blas']; before = blas(); "
              "from models.threads import set_threads; set_threads(2); print(json.dumps([before, blas()]))")
    result = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    before, after = json.loads(result.stdout)
    assert before and all(n == 2 for n in before) and after == [1] * len(before)


def test_a_loader_worker_prepares_the_very_batches_of_the_training_process(data, tmp_path):
    """Batches made by a worker process while steps run give the same weights as batches made between steps."""
    train(tmp_path / "here", config(data, steps=3), progress=False)
    train(tmp_path / "worker", config(data, steps=3, loader_workers=1), progress=False)
    a, b = weights(tmp_path / "here" / CHECKPOINT), weights(tmp_path / "worker" / CHECKPOINT)
    assert a.keys() == b.keys() and all(torch.equal(a[key], b[key]) for key in a)


def test_the_voxel_cache_is_bounded_in_bytes_and_keeps_the_latest_object(tmp_path):
    """Object voxels read for samples are kept as their non-empty voxels up to a byte budget (at 200^3 one object is
    128 MB dense), the latest always; an object given again from the cache equals its file."""
    from renderer.voxels import load_voxels

    first = make_fake_dataset(tmp_path / "a", samples=2, resolution=16)
    second = make_fake_dataset(tmp_path / "b", samples=2, resolution=16, seed=1)
    files = {index: load_voxels(VoxelRenderSet([first, second], grid_size=16).scene(index).voxels_path()) for index in (0, 2)}
    assert 0 < (files[0][..., 3] > 0).sum() < 16**3  # not all empty nor all full: the compact form is exercised
    stored = (files[0].reshape(-1, 4).any(axis=1)).sum() * (4 * 4 + 8)  # rows and their flat indices
    dataset = VoxelRenderSet([first, second], grid_size=16, voxel_cache_bytes=stored)
    for index in (0, 2, 1):
        np.testing.assert_array_equal(dataset.object_voxels(index)[0], files[index // 2 * 2])
        assert list(dataset._voxels) == [str(dataset.scene(index).voxels_path())]
    roomy = VoxelRenderSet([first, second], grid_size=16, voxel_cache_bytes=2 * 16**3 * 4 * 4)
    reads = []
    read = roomy._load_voxels
    roomy._load_voxels = lambda path: reads.append(path) or read(path)
    for index in (0, 2, 1, 0):  # the first object again, rebuilt from the cache, not read
        np.testing.assert_array_equal(roomy.object_voxels(index)[0], files[index // 2 * 2])
    assert len(reads) == 2
    assert len(roomy._voxels) == 2 and roomy.object_voxels(1) is roomy.object_voxels(0)  # the latest kept dense
