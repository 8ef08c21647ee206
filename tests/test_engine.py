"""The live engine: cached renders equal uncached ones, the object crop equals the full grid, newest frame wins."""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import numpy as np
import pytest
import torch

from models.engine.async_render import AsyncRenderer
from models.engine.cropped_encoder import CroppedVoxelEncoder, NarrowGround
from models.engine.onednn import cpu_can_run_bfloat16
from models.engine.receptive import conv_chain
from models.engine.render_engine import (
    BF16_BOUND,
    RenderEngine,
    changed_spans,
    resolve_precision,
)
from models.networks.checkpoint import save_model
from models.networks.config import CompactConfig, PaperConfig, ShaderRefinerConfig
from models.networks.inference import prepare_for_inference
from models.networks.nvr import build_model
from renderer.camera import Camera
from renderer.errors import InputError
from renderer.floor_light import lit_floor_image
from renderer.grid import ground_grid, occupied_spans, scene_grid
from renderer.objects.demo import DEMO_DIR
from renderer.scene import (
    CameraSpec,
    EnvironmentSpec,
    FloorSpec,
    LightSpec,
    MaterialSpec,
    ObjectSpec,
    PaintOp,
    Scene,
    SkySpec,
    load_scene,
    replaced,
)
from renderer.shading import FAST_QUALITY, FULL_QUALITY, ShaderQuality, shade_objects, shade_scene
from renderer.splat import floor_mask, ground_and_background, splat_scene
from renderer.voxels import load_voxels, save_voxels

# Grid 64 (not 128) keeps each render at a few milliseconds; the object still fills only part of it.
TINY_COMPACT = CompactConfig(grid_size=64, output_size=64, voxel_channels=(4, 8, 8), latent_channels=16,
                             light_channels=8, decoder_channels=(8, 8), splat_channels=4, unet_channels=(4, 8))
TINY_PAPER = PaperConfig(grid_size=64, output_size=64, voxel_channels=(4, 4, 4, 8, 8), voxel_res_blocks=2,
                         latent_channels=16, pre_light_blocks=2, light_channels=8, post_light_blocks=1,
                         decoder_channels=(8, 8), splat_channels=4, unet_channels=(4, 8), unet_mid_blocks=1)


@pytest.fixture(autouse=True)
def single_thread():
    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)


def random_model(config, architecture: str = "nvr_plus", seed: int = 0):
    """A random network whose BatchNorms have random statistics, so folded convolutions get non-zero biases
    (with zero biases, empty space gives zero features and a wrong crop halo could go unnoticed), and
    whose light code is strong enough that a light edit visibly changes the image."""
    torch.manual_seed(seed)
    model = build_model(architecture, config).eval()
    model.light_decoder.light_mlp[-1].weight.data *= 30.0
    for module in model.modules():
        if isinstance(module, (torch.nn.BatchNorm2d, torch.nn.BatchNorm3d)):
            module.running_mean.uniform_(-0.5, 0.5)
            module.running_var.uniform_(0.5, 2.0)
            module.weight.data.uniform_(0.5, 1.5)
            module.bias.data.uniform_(-0.5, 0.5)
    return model


def engine(model, crop: bool = True) -> RenderEngine:
    """The CPU engine in fp32, whose images these tests compare exactly (bf16 and CUDA have their own tests)."""
    return RenderEngine(model, crop=crop, threads=1, precision="fp32", device="cpu")


@pytest.fixture(scope="module")
def model():
    return random_model(TINY_COMPACT)


@pytest.fixture
def scene(two_color_box) -> Scene:
    return two_color_box


VOXEL_BRANCH = ["gather", "voxel_branch", "splat", "splat_branch", "light"]  # edits that keep the splat layout
PLACED = ["gather", "voxel_branch", "splat_layout", "splat", "splat_branch", "light"]  # edits that move pixels
# The same, for edits that also change the lit floor (TINY_COMPACT reads it, as the shipped model does).
FLOOR_BRANCH = ["gather", "voxel_branch", "splat", "floor_light", "splat_branch", "light"]
FLOOR_PLACED = ["gather", "voxel_branch", "splat_layout", "splat", "floor_light", "splat_branch", "light"]
# edit -> the stages the module docstring of models/engine/render_engine.py says it reruns
EDITS = {
    "light": (lambda s: s.with_changes(light=LightSpec((-0.8, 2.6, 1.2))), ["floor_light", "splat_branch", "light"]),
    "floor color": (lambda s: s.with_changes(floor=FloorSpec((0.9, 0.2, 0.1))), ["background", *FLOOR_BRANCH]),
    "paint stroke": (lambda s: s.with_changes(paint=(PaintOp("region", (0.0, 1.0, 0.0), seed=(5, 11, 5)),)),
                     ["paint", "pool", *VOXEL_BRANCH]),
    "object color": (lambda s: s.with_changes(object=replace(s.object, color=(0.9, 0.9, 0.1))),
                     ["paint", "pool", *VOXEL_BRANCH]),
    "move": (lambda s: s.with_changes(object=replace(s.object, translation=(0.3, -0.2))), ["placement", *PLACED]),
    "rotate": (lambda s: s.with_changes(object=replace(s.object, rotation_deg=-35.0)), ["placement", *PLACED]),
    # 0.8 -> 1.2 keeps the merge factors at 1 (a 0.0625 voxel stays wider than the 0.04 grid voxel): no re-pooling
    "scale": (lambda s: s.with_changes(object=replace(s.object, scale=(1.2, 1.0, 0.9))), ["placement", *PLACED]),
    "camera": (lambda s: s.with_changes(camera=CameraSpec(45.0)), ["placement", "background", *FLOOR_PLACED]),
}



def test_an_engine_given_the_object_voxels_renders_them_without_loading_the_object_again(model, scene):
    """The editor shares its voxel cache: the engine paints the voxels it is given (read-only), once per object."""
    painted = scene.with_changes(paint=(PaintOp("region", (0.1, 0.9, 0.1), seed=(6, 5, 6)),))
    given = []

    def source(s: Scene) -> np.ndarray:
        given.append(s.object.voxels)
        rgba = load_voxels(s.voxels_path())
        rgba.flags.writeable = False
        return rgba

    shared = RenderEngine(model, threads=1, precision="fp32", device="cpu", object_source=source)
    for s in (scene, painted, scene):
        np.testing.assert_array_equal(shared.render(s), engine(model).render(s))
    assert given == ["box.npz"]
    other = replace(scene.object, voxels="other.npz")
    save_voxels(scene.base_dir / "other.npz", np.flip(load_voxels(scene.voxels_path()), axis=1))
    shared.render(scene.with_changes(object=other))
    assert given == ["box.npz", "other.npz"]

@pytest.mark.parametrize("edit", EDITS)
def test_cached_render_equals_uncached_and_reruns_only_its_stages(model, scene, edit):
    make, expected = EDITS[edit]
    edited = make(scene)
    live = engine(model)
    live.render(scene)
    image = live.render(edited)
    assert list(live.last_report.stages_run) == expected
    fresh = engine(model, crop=False).render(edited)  # nothing cached, full grid
    assert image.shape == (64, 64, 3) and image.dtype == np.float32
    np.testing.assert_allclose(image, fresh, rtol=0, atol=1e-5)
    assert np.abs(image - live.render(scene)).max() > 1e-4  # the edit changed the image (the test can fail)


def test_same_scene_runs_nothing_and_first_render_runs_everything(model, scene):
    live = engine(model)
    first = live.render(scene)
    assert live.last_report.stages_run == ("voxels", "paint", "pool", "placement", "background", "gather",
                                           "voxel_branch", "shell", "splat_layout", "splat", "floor_light",
                                           "splat_branch", "light")
    again = live.render(scene)
    assert live.last_report.stages_run == ()
    np.testing.assert_array_equal(first, again)
    again[:] = 0.0  # the caller's copy: the cache is untouched
    np.testing.assert_array_equal(live.render(scene), first)


def test_without_the_lit_floor_a_light_move_reruns_only_the_light_stage(scene):
    model = random_model(replace(TINY_COMPACT, floor_light_input=False))
    live = engine(model)
    live.render(scene)
    moved = scene.with_changes(light=LightSpec((-0.8, 2.6, 1.2)))
    image = live.render(moved)
    assert live.last_report.stages_run == ("light",)
    np.testing.assert_allclose(image, engine(model, crop=False).render(moved), rtol=0, atol=1e-5)


def test_nvr_has_no_splat_stages(scene):
    live = engine(random_model(TINY_COMPACT, "nvr"))
    image = live.render(scene)
    assert not any(stage.startswith("splat") for stage in live.last_report.stages_run)
    np.testing.assert_allclose(image, engine(random_model(TINY_COMPACT, "nvr"), crop=False).render(scene), atol=1e-5)


@pytest.mark.parametrize("translation", [(0.0, 0.0), (-0.9, 0.9), (0.95, -0.6)])
def test_occupied_region_equals_full_grid(model, scene, translation):
    """Centre, and near the grid's left/near and right/far sides (the crop meets the grid border)."""
    moved = scene.with_changes(object=replace(scene.object, translation=translation))
    live = engine(model)
    image = live.render(moved)
    assert 0.0 < live.last_report.grid_fraction < 0.6  # the crop really is a part of the grid
    np.testing.assert_allclose(image, engine(model, crop=False).render(moved), rtol=0, atol=1e-5)


def test_object_outside_the_grid_renders_the_ground(model, scene):
    away = scene.with_changes(object=replace(scene.object, translation=(40.0, 40.0)))
    live = engine(model)
    image = live.render(away)
    assert live.last_report.grid_fraction == 0.0
    np.testing.assert_allclose(image, engine(model, crop=False).render(away), rtol=0, atol=1e-5)


def test_ground_grid_is_the_scene_grid_without_object():
    grid = ground_grid((0.25, 0.5, 0.75), 30.0, 32)
    away = ObjectSpec(translation=(40.0, 40.0))  # outside the grid
    np.testing.assert_array_equal(grid, scene_grid(np.ones((16, 16, 16, 4), np.float32), away, (0.25, 0.5, 0.75), 30.0, 32))
    np.testing.assert_array_equal(ground_grid((0.25, 0.5, 0.75), 30.0, 32, columns=5), grid[:, :, :5])
    occupied = grid[..., 3] == 1.0
    assert occupied.any() and not occupied.all()
    np.testing.assert_array_equal(grid[occupied, :3], np.tile([0.25, 0.5, 0.75], (occupied.sum(), 1)))
    assert not grid[~occupied].any()
    # At elevation 0 row r of a 32-grid (0.08 per row, centred on the look-at height 0.5, row 0 on top) has
    # its centre at y = 1.78 - 0.08 (r + 0.5); the ground is the 3-voxel slab y in [-0.24, 0): rows 22, 23, 24,
    # at every depth and column.
    flat = ground_grid((1.0, 1.0, 1.0), 0.0, 32)[..., 3] == 1.0
    assert np.flatnonzero(flat.any(axis=(0, 2))).tolist() == [22, 23, 24]
    assert flat[:, 22:25, :].all()


def test_changed_spans_leave_out_empty_object_rows_but_not_replaced_ground():
    object_rows = np.array([False, True, False, False])  # P = 2 object rows: row 0 empty, row 1 occupied; empty, floor
    ground = np.zeros((4, 5, 6), dtype=bool)
    ground[:, 4, :] = True
    indices = np.where(ground, 3, 2).astype(np.int32)  # the floor row P + 1, the empty row P
    indices[0, 0, 0] = 0  # the empty object row equals the empty row: nothing changes
    indices[1, 1, 2] = 1
    whole = [(0, 4), (0, 5), (0, 6)]
    assert changed_spans(indices, object_rows, ground, whole) == ((1, 2), (1, 2), (2, 3))
    # Over a window of the grid the spans are the grid's.
    assert changed_spans(indices[1:, 1:, 2:], object_rows, ground, [(1, 4), (1, 5), (2, 6)]) == ((1, 2), (1, 2), (2, 3))
    indices[3, 4, 5] = 0  # an object row, even an empty one, in place of a floor voxel removes it
    assert changed_spans(indices, object_rows, ground, whole) == ((1, 4), (1, 5), (2, 6))
    indices[3, 4, 5] = 2  # the empty row on a ground voxel: the floor voxel is gone too
    assert changed_spans(indices, object_rows, ground, whole) == ((1, 4), (1, 5), (2, 6))
    assert changed_spans(np.where(ground, 3, 2).astype(np.int32), object_rows, ground, whole) is None


def test_crop_around_a_small_part_of_the_object_box_equals_the_full_grid(model, scene):
    """A blob in one corner of the object's box: the crop follows the blob, not the box, and stays exact."""
    rgba = np.zeros((16, 16, 16, 4), np.float32)
    rgba[1:4, 0:3, 11:15] = (0.9, 0.8, 0.1, 1.0)
    save_voxels(scene.base_dir / "corner.npz", rgba)
    corner = scene.with_changes(object=replace(scene.object, voxels="corner.npz", scale=(1.0, 1.0, 1.0)))
    live = engine(model)
    image = live.render(corner)
    assert 0.0 < live.last_report.grid_fraction < 0.1
    np.testing.assert_allclose(image, engine(model, crop=False).render(corner), rtol=0, atol=1e-5)


def test_preview_is_the_splat_over_the_lit_floor_unless_only_the_light_changed(model, scene):
    live = engine(model)
    live.render(scene)
    lit = scene.with_changes(light=LightSpec((0.0, 3.0, 0.0)))
    np.testing.assert_array_equal(live.preview(lit), live.render(lit))
    assert live.last_report.stages_run == ()  # the preview already rendered it
    moved = lit.with_changes(object=replace(lit.object, translation=(0.2, 0.2)))
    preview = live.preview(moved)
    assert live.last_report.preview and live.last_report.stages_run == ("splat_layout", "splat")
    # Expected, from the renderer's own functions: the object's pixels of the splat, the lit floor elsewhere.
    camera = Camera.from_scene(moved, 64)
    splat = splat_scene(moved, load_voxels(scene.voxels_path()), (0.5, 0.6, 0.7), size=64)
    on_object = np.any(splat != ground_and_background(floor_mask(camera), (0.5, 0.6, 0.7)), axis=-1)
    assert on_object.any() and not on_object.all()
    expected = np.where(on_object[..., None], splat, lit_floor_image(camera, (0.0, 3.0, 0.0), (0.5, 0.6, 0.7)))
    np.testing.assert_array_equal(preview, expected)
    live.render(moved)
    assert "splat" not in live.last_report.stages_run  # the release reuses the preview's splat


# --- the crop arithmetic, against the network itself ----------------------------------------------


@pytest.mark.parametrize("config", [TINY_COMPACT, TINY_PAPER], ids=["compact", "paper"])
def test_changed_outputs_match_a_perturbation(config):
    """Perturbing one voxel changes exactly the 3D-stack outputs the arithmetic predicts (up to where the
    perturbation happens to cancel, so predicted must contain observed and observed must reach its corners)."""
    model = prepare_for_inference(random_model(config, "nvr"))
    enc = model.voxel_encoder
    chain = conv_chain(list(enc.stages.modules()) + list(enc.residual.modules()), 3)
    g = config.grid_size
    base = torch.zeros(1, 4, g, g, g)
    with torch.no_grad():
        reference = enc.residual(enc.stages(base))
        for voxel in [(0, 0, 0), (30, 17, 63), (63, 40, 5)]:
            poked = base.clone()
            poked[(0, slice(None), *voxel)] = 1.0
            changed = (enc.residual(enc.stages(poked)) - reference).abs().amax(dim=(0, 1)) > 0
            observed = occupied_spans(changed.numpy())
            predicted = chain.changed_outputs(tuple((v, v + 1) for v in voxel), (g, g, g))
            assert observed == predicted


@pytest.mark.parametrize("config", [TINY_COMPACT, TINY_PAPER], ids=["compact", "paper"])
@pytest.mark.parametrize("box", [((20, 30), (25, 40), (30, 38)), ((0, 6), (50, 64), (60, 64))])
def test_cropped_encoder_equals_full_encoder(config, box):
    model = prepare_for_inference(random_model(config, "nvr", seed=1))
    g = config.grid_size
    gen = torch.Generator().manual_seed(0)
    background = (torch.rand(1, 4, g, g, g, generator=gen) > 0.9).float()
    scene = background.clone()
    region = tuple(slice(*span) for span in box)
    scene[(0, slice(None), *region)] = torch.rand(4, *(hi - lo for lo, hi in box), generator=gen)
    cropped = CroppedVoxelEncoder(model.voxel_encoder, g)
    with torch.no_grad():
        plan = cropped.plan(box)
        latent = cropped.encode(cropped.background(background), plan, scene[(0, slice(None), *plan.grid)][None])
        full = model.encode_voxels(scene)
    torch.testing.assert_close(latent, full, rtol=0, atol=1e-5)


# Eight latent blocks reach all 16 latent columns of a 64-grid: only the 3D stack runs on a narrow ground.
DEEP_LATENT = replace(TINY_COMPACT, pre_light_blocks=8)


@pytest.mark.parametrize("config, narrow, narrow_volume", [
    # Hand count: volume column o reads input columns [4(o - 1), 4(o + 2)), so only the first and last reach the
    # padding: 3 volume columns (12 input columns), the middle one at index 1. The four 3x3 convolutions of the
    # two latent blocks reach 4 columns further: 5 + 1 + 5 latent columns (44 input columns), the middle at 5.
    (TINY_COMPACT, NarrowGround(44, 5), NarrowGround(12, 1)),
    (DEEP_LATENT, None, NarrowGround(12, 1)),
], ids=["compact", "deep latent"])
def test_narrow_ground_gives_the_full_background(config, narrow, narrow_volume):
    model = prepare_for_inference(random_model(config, "nvr"))
    cropped = CroppedVoxelEncoder(model.voxel_encoder, 64)
    assert (cropped.narrow, cropped.narrow_volume) == (narrow, narrow_volume)
    ground = ground_grid((0.3, 0.6, 0.9), 25.0, 64)
    assert (ground == ground[:, :, :1]).all()  # the ground is the same in every column
    with torch.no_grad():
        full = cropped.background(torch.from_numpy(ground).permute(3, 0, 1, 2)[None])
        narrow = cropped.background(torch.from_numpy(ground[:, :, :12].copy()).permute(3, 0, 1, 2)[None])
    torch.testing.assert_close(narrow.volume, full.volume, rtol=0, atol=1e-6)
    torch.testing.assert_close(narrow.projected, full.projected, rtol=0, atol=1e-6)
    torch.testing.assert_close(narrow.latent, full.latent, rtol=0, atol=1e-6)


def test_no_narrow_ground_when_it_would_not_be_narrower():
    assert CroppedVoxelEncoder(prepare_for_inference(random_model(TINY_PAPER, "nvr")).voxel_encoder, 64).narrow_volume is None


# --- loading -------------------------------------------------------------------------------------------


def test_load_checks_the_architecture(tmp_path, model, scene):
    path = tmp_path / "w.safetensors"
    save_model(path, model, TINY_COMPACT)
    live = RenderEngine.load(path, "nvr_plus", threads=1, precision="fp32", device="cpu")
    assert live.output_size == 64 and "w.safetensors" in live.model_name
    np.testing.assert_allclose(live.render(scene), engine(model).render(scene), atol=1e-6)
    with pytest.raises(InputError, match="not nvr"):
        RenderEngine.load(path, "nvr")
    with pytest.raises(InputError, match="unknown network architecture"):
        RenderEngine.load(path, "splat")


def test_bfloat16_agrees_with_float32_within_its_bound_on_the_shipped_model():
    if not cpu_can_run_bfloat16():
        with pytest.raises(InputError, match="cannot run bf16"):
            resolve_precision("bf16")
        pytest.skip("this CPU cannot run bf16 convolutions (oneDNN needs AVX512 or AVX-NE-CONVERT)")
    demo = load_scene(DEMO_DIR / "scene.json")
    fp32, bf16 = (RenderEngine.load(None, threads=2, precision=p, device="cpu") for p in ("fp32", "bf16"))
    assert bf16.dtype == torch.bfloat16 and next(bf16.model.parameters()).dtype == torch.bfloat16
    far = replace(demo.object, translation=(40.0, 40.0))  # the object outside the grid: the empty floor
    for light, placed in ((demo.light.position, demo.object), ((-1.5, 3.5, 1.5), demo.object),
                          ((30.0, 0.05, -30.0), demo.object), ((0.0, 50.0, 0.0), far)):  # and extreme lights
        scene = replace(demo, light=replace(demo.light, position=light), objects=(placed,))
        exact, fast = fp32.render(scene), bf16.render(scene)
        assert fast.dtype == np.float32 and np.isfinite(fast).all()
        difference = (fast.astype(np.float64) - exact) * 255.0
        assert 0.0 < np.abs(difference).max() <= BF16_BOUND["max_abs"]  # really rounded, and only a little
        assert np.mean(difference**2) <= BF16_BOUND["mse"]
    assert resolve_precision("fp32") == "fp32" and resolve_precision("auto") in ("fp32", "bf16")
    with pytest.raises(InputError, match="unknown precision"):
        RenderEngine(random_model(TINY_COMPACT), precision="fp16")


def test_device_choice():
    from models.engine.render_engine import resolve_device

    expected = "cuda" if torch.cuda.is_available() else "cpu"
    assert resolve_device("auto").type == expected and resolve_device("cpu").type == "cpu"
    with pytest.raises(InputError, match="unknown device"):
        resolve_device("tpu")
    if not torch.cuda.is_available():
        with pytest.raises(InputError, match="no CUDA GPU"):
            RenderEngine(random_model(TINY_COMPACT), device="cuda")
    # bf16 is chosen only for the CPU, where its bound is tested; a GPU runs fp32 unless asked.
    assert resolve_precision("auto", torch.device("cuda")) == "fp32"


# --- the worker thread ---------------------------------------------------------------------------------


class SlowEngine:
    """Renders a constant image of the scene's light x after a delay; records what it rendered."""

    def __init__(self, seconds: float):
        self.seconds = seconds
        self.rendered: list[float] = []
        self.started = threading.Event()
        self.last_report = None

    def render(self, scene: Scene) -> np.ndarray:
        self.started.set()
        time.sleep(self.seconds)
        self.rendered.append(scene.light.position[0])
        return np.full((4, 4, 3), scene.light.position[0], np.float32)

    preview = render


def lit(x: float) -> Scene:
    return Scene.single(object=ObjectSpec(voxels="unused.npz"), light=LightSpec((x, 2.75, 0.0)))


def test_superseded_requests_are_dropped_and_never_overwrite_newer_frames():
    slow = SlowEngine(0.2)
    frames = []
    worker = AsyncRenderer(slow, on_frame=frames.append)
    try:
        first = worker.submit(lit(0.1))
        assert slow.started.wait(5.0)  # request 1 is rendering
        worker.submit(lit(0.2), preview=True)  # waits, then is superseded by the next
        last = worker.submit(lit(0.3))
        frame = worker.wait_for(last, timeout=5.0)
        assert worker.wait_idle(5.0)
    finally:
        worker.close()
    assert slow.rendered == [0.1, 0.3]
    assert [f.sequence for f in frames] == [first, last] and frame.sequence == last
    assert frame.image[0, 0, 0] == pytest.approx(0.3) and not frame.preview
    assert worker.latest() is frame


def test_a_request_with_a_size_renders_the_final_image_at_that_size(scene):
    live = engine(refiner())
    worker = AsyncRenderer(live)
    try:
        frame = worker.wait_for(worker.submit(scene, size=96), 10)
    finally:
        worker.close()
    assert frame.error is None and not frame.preview
    np.testing.assert_array_equal(frame.image, live.render_sized(scene, 96))


def test_a_failing_scene_reports_its_error_and_the_worker_goes_on(scene, model):
    worker = AsyncRenderer(engine(model))
    try:
        bad = worker.wait_for(worker.submit(scene.with_changes(object=replace(scene.object, voxels="missing.npz"))), 10)
        good = worker.wait_for(worker.submit(scene), 10)
    finally:
        worker.close()
    assert bad.image is None and "missing.npz" in bad.error
    assert good.error is None and good.image.shape == (64, 64, 3)


def test_cli_renders_with_the_engine(tmp_path, model, scene):
    from app.cli import run
    from renderer.io import load_image
    from renderer.scene import save_scene

    save_model(tmp_path / "w.safetensors", model, TINY_COMPACT)
    save_scene(scene, tmp_path / "scene.json")
    out = tmp_path / "out.png"
    assert run(["render", str(tmp_path / "scene.json"), "-o", str(out), "--renderer", "nvr+",
                "--model", str(tmp_path / "w.safetensors"), "--precision", "fp32"]) == 0
    image, _ = load_image(out)
    np.testing.assert_allclose(image, engine(model).render(scene), atol=1 / 255)


# --- NVR+ refining the voxel shader ----------------------------------------------------------------

TINY_REFINER = ShaderRefinerConfig(grid_size=64, output_size=64, voxel_channels=(4, 8, 8), latent_channels=16,
                                   light_channels=8, decoder_channels=(8, 8), splat_channels=4, unet_channels=(4, 8))


# The same at half the image's side: its correction is computed at 32^2 and upsampled onto the 64^2 shaded image.
TINY_HALF_REFINER = replace(TINY_REFINER, decoder_channels=(8,), correction_downsampling=2)
REFINERS = {"full": TINY_REFINER, "half": TINY_HALF_REFINER}


def refiner(seed: int = 0, trained: bool = True, config: ShaderRefinerConfig = TINY_REFINER):
    """A random refiner; `trained`: its correction layer is random too (a fresh one starts at zero)."""
    model = random_model(config, seed=seed)
    if trained:
        torch.manual_seed(seed + 1)
        for parameter in model.rerender.to_rgb.parameters():
            parameter.data.normal_(0.0, 0.05)
    else:
        torch.manual_seed(seed)
        model = build_model("nvr_plus", config).eval()
    return model


def _shaded_image(scene, grid_size: int, quality: ShaderQuality = FULL_QUALITY, size: int = 64) -> np.ndarray:
    """The voxel shader's `size`^2 image of `scene` as a network reads it (no reflection of the object in the floor),
    its object voxels merged as for a grid of `grid_size`^3, computed without the engine."""
    return shade_scene(scene, load_voxels(scene.voxels_path()), scene.floor.color, size, grid_size,
                       reflection=False, quality=quality).image


@pytest.mark.parametrize("factor, engine_factor, shaded_grid", [(1, None, 64), (2, None, 128), (2, 1, 64)])
def test_an_untrained_refiner_renders_the_shaded_image(scene, factor, engine_factor, shaded_grid):
    """The network's grid is 64^3; the shader merges the object voxels as for the configuration's `factor` times finer
    grid, unless the engine is told another factor. A slide and a turn keep the shader's geometry."""
    torch.manual_seed(0)
    model = build_model("nvr_plus", replace(TINY_REFINER, shading_grid_factor=factor)).eval()
    live = RenderEngine(model, threads=1, precision="fp32", device="cpu", shading_grid_factor=engine_factor)
    scene = replaced(scene, object=replace(scene.object, translation=(0.1, -0.05)))
    np.testing.assert_allclose(live.render(scene), _shaded_image(scene, shaded_grid), rtol=0, atol=1e-6)
    slid = replaced(scene, object=replace(scene.object, translation=(-0.12, 0.07)))
    turned = replaced(slid, object=replace(slid.object, rotation_deg=slid.object.rotation_deg + 25.0))
    for edited in (slid, turned):
        np.testing.assert_allclose(live.render(edited), _shaded_image(edited, shaded_grid), rtol=0, atol=1e-6)
        assert "shade_geometry" not in live.last_report.stages_run
        assert "shade_surface" in live.last_report.stages_run


def test_at_the_fast_quality_an_untrained_refiner_renders_the_fast_shading(scene):
    """The engine's shader quality is what its network reads: untrained, it renders the fast shaded image, after a
    light edit too (only the light's stages rerun), and not the full one."""
    torch.manual_seed(0)
    model = build_model("nvr_plus", TINY_REFINER).eval()
    fast = RenderEngine(model, threads=1, precision="fp32", device="cpu", shader_quality="fast")
    np.testing.assert_allclose(fast.render(scene), _shaded_image(scene, 64, FAST_QUALITY), rtol=0, atol=1e-6)
    lit = replace(scene, light=replace(scene.light, position=(-0.7, 2.5, 0.6)))
    image = fast.render(lit)
    assert not {"shade_geometry", "shade_surface"} & set(fast.last_report.stages_run)
    np.testing.assert_allclose(image, _shaded_image(lit, 64, FAST_QUALITY), rtol=0, atol=1e-6)
    assert np.abs(image - _shaded_image(lit, 64)).max() > 1e-3  # the fast shading is not the full one
    with pytest.raises(InputError, match="unknown shader quality"):
        RenderEngine(model, shader_quality="draft")


def test_refiner_drag_preview_is_the_shaded_image(scene):
    """While the object turns or slides, the preview is the shader's image, its geometry kept from the render before;
    the settled render then reuses the preview's stages, and a second preview of the same scene reruns nothing."""
    live = engine(refiner(trained=False))
    scene = replaced(scene, object=replace(scene.object, translation=(-0.08, 0.06)))
    live.render(scene)
    turned = replaced(scene, object=replace(scene.object, rotation_deg=scene.object.rotation_deg + 25.0))
    slid = replaced(turned, object=replace(turned.object, translation=(0.1, -0.05)))
    for edited in (turned, slid):
        np.testing.assert_allclose(live.preview(edited), _shaded_image(edited, 128), rtol=0, atol=1e-6)
        assert {"shade_surface", "shade_lighting"} <= set(live.last_report.stages_run)
        assert "shade_geometry" not in live.last_report.stages_run
        np.testing.assert_allclose(live.render(edited), _shaded_image(edited, 128), rtol=0, atol=1e-6)
        assert not {"shade_surface", "shade_lighting"} & set(live.last_report.stages_run)
        live.preview(edited)
        assert live.last_report.stages_run == ()


@pytest.mark.parametrize("resolution", REFINERS)
@pytest.mark.parametrize("edit", EDITS)
def test_refiner_cached_render_equals_uncached(scene, edit, resolution):
    model = refiner(config=REFINERS[resolution])
    edited = EDITS[edit][0](scene)
    live = engine(model)
    live.render(scene)
    image = live.render(edited)
    if edit == "light":  # the object's geometry and what the camera sees of it are kept
        assert list(live.last_report.stages_run) == ["shade_floor", "shade_lighting", "splat_branch", "light"]
    if edit in ("paint stroke", "object color"):  # paint keeps occupancy: the surface stays, its colors are redone
        assert not {"shade_geometry", "shade_surface"} & set(live.last_report.stages_run)
        assert {"shade_colors", "shade_lighting"} <= set(live.last_report.stages_run)
    if edit in ("floor color", "floor paint"):  # the shader's object stages do not read the floor
        assert not {"shade_geometry", "shade_surface", "shade_colors"} & set(live.last_report.stages_run)
        assert {"shade_floor", "shade_lighting"} <= set(live.last_report.stages_run)
    np.testing.assert_allclose(image, engine(model, crop=False).render(edited), rtol=0, atol=1e-5)
    assert np.abs(image - live.render(scene)).max() > 1e-4


@pytest.mark.parametrize("resolution", REFINERS)
def test_a_saved_refiner_renders_the_same_after_loading(scene, tmp_path, resolution):
    model = refiner(config=REFINERS[resolution])
    save_model(tmp_path / "refiner.safetensors", model, REFINERS[resolution])
    loaded = RenderEngine.load(tmp_path / "refiner.safetensors", threads=1, precision="fp32", device="cpu")
    np.testing.assert_array_equal(loaded.render(scene), engine(model).render(scene))
    # The preview while dragging is the shaded image the full render corrects.
    preview = loaded.preview(scene.with_changes(object=replace(scene.object, translation=(0.2, 0.1))))
    assert preview.shape == (64, 64, 3) and np.all(np.isfinite(preview))


@pytest.mark.parametrize("resolution", REFINERS)
def test_compiled_image_passes_equal_torch_in_the_engine(scene, resolution):
    """On the CPU the engine joins the splat branch's inputs and applies the correction in compiled passes
    (models/engine/image_passes.py); with torch's operations instead the images are the same."""
    model = refiner(config=REFINERS[resolution])
    live, with_torch = engine(model), engine(model)
    assert live._passes_on_cpu
    with_torch._passes_on_cpu = False
    for edited in (scene, EDITS["light"][0](scene), EDITS["move"][0](scene)):
        image = live.render(edited)
        np.testing.assert_allclose(image, with_torch.render(edited), rtol=0, atol=1e-5)
        assert np.abs(image - _shaded_image(edited, 128)).max() > 1e-2  # the correction is not nothing


@pytest.mark.parametrize("resolution", REFINERS)
def test_a_refiner_renders_any_size_as_the_shaded_image_at_that_size_corrected(scene, resolution):
    """render_sized at another size than the network's 64: the shader's image at that size, corrected by the gain and
    offset the network computes at its own. Untrained (no correction), that is the shaded image itself; with the
    correction layer giving a constant gain and offset, the shaded image times exp(gain) plus the offset."""
    untrained = engine(refiner(trained=False, config=REFINERS[resolution]))
    for size in (16, 17, 48, 96):  # the least size, an odd one (the correction sampled, not area-averaged), larger
        np.testing.assert_allclose(untrained.render_sized(scene, size), _shaded_image(scene, 128, size=size),
                                   rtol=0, atol=1e-6)
    model = refiner(trained=False, config=REFINERS[resolution])
    with torch.no_grad():
        model.rerender.to_rgb[0].weight.zero_()
        model.rerender.to_rgb[0].bias.copy_(torch.tensor([-0.3, 0.2, 0.0, 0.05, -0.02, 0.1]))
    gain, offset = np.exp(np.float32([-0.3, 0.2, 0.0])), np.float32([0.05, -0.02, 0.1])
    for size in (17, 96):
        expected = np.clip(_shaded_image(scene, 128, size=size) * gain + offset, 0.0, 1.0)
        np.testing.assert_allclose(engine(model).render_sized(scene, size), expected, rtol=0, atol=1e-5)


def test_render_sized_keeps_the_live_stages_and_shows_the_networks_picture(scene):
    """At the network's own size render_sized is render; at another it leaves the live caches as they were (the next
    live render of the scene runs nothing), and its image, area-averaged to the network's size, differs from the
    network's image about as the shader's own images at the two sizes differ (along the silhouette, which the larger
    one draws finer): the correction is the same picture at both sizes."""
    live = engine(refiner())
    image = live.render(scene)
    np.testing.assert_array_equal(live.render_sized(scene, 64), image)
    larger = live.render_sized(scene, 128)
    live.render(scene)
    assert live.last_report.stages_run == ()

    def mse_to_its_average(small: np.ndarray, large: np.ndarray) -> float:
        return float(np.mean((large.reshape(64, 2, 64, 2, 3).mean(axis=(1, 3)) - small) ** 2)) * 255**2

    shader_alone = mse_to_its_average(_shaded_image(scene, 128), _shaded_image(scene, 128, size=128))
    assert 1.0 < shader_alone < mse_to_its_average(image, larger) < shader_alone + 2.0  # measured: 5.6 and 6.4


def test_a_network_that_draws_the_image_renders_its_own_size_only(model, scene):
    live = engine(model)
    assert not live.renders_any_size
    with pytest.raises(InputError, match="renders 64x64 only"):
        live.render_sized(scene, 96)
    np.testing.assert_array_equal(live.render_sized(scene, 64), live.render(scene))


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA GPU")
@pytest.mark.parametrize("network", ["compact", "half-resolution refiner"])
def test_on_a_cuda_gpu_every_edit_renders_what_a_fresh_engine_and_the_cpu_render(model, scene, network):
    """A GPU's images agree with a fresh engine's and the CPU's within float rounding, not bit for bit (on a lent
    H200 two engines rendered one scene up to 6e-8 apart)."""
    network_model = model if network == "compact" else refiner(config=TINY_HALF_REFINER)
    gpu = RenderEngine(network_model, threads=1, precision="fp32", device="cuda")
    gpu.render(scene)
    for name, (edit, _) in EDITS.items():
        edited = edit(scene)
        image = gpu.render(edited)
        fresh = RenderEngine(network_model, threads=1, precision="fp32", device="cuda").render(edited)
        np.testing.assert_allclose(image, fresh, rtol=0, atol=1e-5, err_msg=name)
        np.testing.assert_allclose(image, engine(network_model).render(edited), rtol=0, atol=1e-3, err_msg=name)


ENVIRONMENT_EDITS = {
    "turn": lambda s: replace(s, environment=replace(s.environment, rotation_deg=75.0)),
    "strength": lambda s: replace(s, environment=replace(s.environment, strength=1.6)),
    "sun": lambda s: replace(s, environment=replace(s.environment, sky=SkySpec(22.0, -60.0, 3.0))),
    "material": lambda s: replaced(s, object=replace(s.object, material=MaterialSpec(0.2, 0.5, 1.0))),
    "area light on": lambda s: replace(s, light=replace(s.light, enabled=True)),
}


@pytest.mark.parametrize("edit", ENVIRONMENT_EDITS)
def test_environment_edits_show_the_shaders_image_rerun_only_the_lighting_and_equal_uncached(scene, edit):
    """A network that does not read the environment: the engine shows the shader's image and says so. An environment
    or material edit reruns the lighting alone, and its image equals a fresh engine's."""
    model = refiner()
    lit = replace(scene, environment=EnvironmentSpec(sky=SkySpec(40.0, 30.0)), light=replace(scene.light, enabled=False))
    edited = ENVIRONMENT_EDITS[edit](lit)
    live = engine(model)
    before = live.render(lit)
    image = live.render(edited)
    stages = set(live.last_report.stages_run)
    assert "shade_lighting" in stages and not {"shade_geometry", "shade_surface", "shade_colors"} & stages
    assert "not trained for environment light" in live.last_report.note
    np.testing.assert_allclose(image, engine(model, crop=False).render(edited), rtol=0, atol=1e-5)
    np.testing.assert_allclose(image, np.clip(_shaded_image(edited, 128), 0.0, 1.0), rtol=0, atol=1e-5)
    assert np.abs(image - before).max() > 1e-3
    assert live.render(scene).shape == (64, 64, 3) and live.last_report.note == ""  # back to the area light: the network


TINY_ENVIRONMENT_REFINER = replace(TINY_HALF_REFINER, environment_input=True)


def environment_refiner(seed: int = 0):
    """A random refiner that reads the environment, its environment code as strong as its light code."""
    model = refiner(seed, config=TINY_ENVIRONMENT_REFINER)
    torch.manual_seed(seed + 2)
    model.light_decoder.environment.mlp[-1].weight.data.normal_(0.0, 3.0)
    return model


@pytest.mark.parametrize("edit", ENVIRONMENT_EDITS)
def test_a_network_that_reads_the_environment_corrects_every_environment_edit_as_a_fresh_engine(scene, edit):
    """Its image is the network's (no note), the edit reruns the shader's lighting and the network's light stage but
    not the voxel branch, and it equals an uncached engine's."""
    model = environment_refiner()
    lit = replace(scene, environment=EnvironmentSpec(sky=SkySpec(40.0, 30.0)), light=replace(scene.light, enabled=False))
    edited = ENVIRONMENT_EDITS[edit](lit)
    live = engine(model)
    before = live.render(lit)
    assert live.last_report.note == ""
    image = live.render(edited)
    stages = set(live.last_report.stages_run)
    assert {"shade_lighting", "lighting", "light"} <= stages and not {"voxel_branch", "splat", "shade_surface"} & stages
    np.testing.assert_allclose(image, engine(model, crop=False).render(edited), rtol=0, atol=1e-5)
    assert np.abs(image - before).max() > 1e-3
    assert np.abs(image - np.clip(_shaded_image(edited, 128), 0.0, 1.0)).max() > 1e-3  # corrected, not the shader's


def test_the_light_input_of_a_network_that_reads_the_environment_is_kept_through_edits_it_does_not_read(scene):
    """Its light input (the probe, the switch, the material) is made again for a light or material edit only."""
    lit = replace(scene, environment=EnvironmentSpec(sky=SkySpec(40.0, 30.0)))
    live = engine(environment_refiner())
    live.render(lit)
    for edited, reread in ((lit.with_changes(floor=FloorSpec((0.9, 0.2, 0.1))), False),
                           (lit.with_changes(object=replace(lit.object, translation=(0.2, 0.1))), False),
                           (lit.with_changes(light=LightSpec((-0.8, 2.6, 1.2))), True)):
        live.render(edited)
        assert ("lighting" in live.last_report.stages_run) == reread


def test_a_network_that_reads_the_environment_shows_the_shaders_image_of_several_objects(scene):
    """Its light input holds one object's material: of two objects it shows the shader's image (the floor's
    reflection too) and says so; a refiner that reads the area light alone renders them itself."""
    two = replace(scene, objects=(scene.object, replace(scene.object, translation=(0.6, -0.4), name="copy")))
    live = engine(environment_refiner())
    image = live.render(two)
    assert "one object's material" in live.last_report.note
    shaded = shade_objects(two, [load_voxels(two.file(o.voxels)) for o in two.objects], two.floor.color, 64, 128)
    np.testing.assert_allclose(image, np.clip(shaded.image, 0.0, 1.0), rtol=0, atol=1e-5)
    plain = engine(refiner())
    plain.render(two)
    assert plain.last_report.note == "" and "voxel_branch" in plain.last_report.stages_run
