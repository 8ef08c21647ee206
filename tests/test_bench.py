"""`nvr bench`: the quick run writes its JSON, report and figure; the Pareto front and the memory probe."""

from __future__ import annotations

import json
import math
from dataclasses import asdict

import numpy as np
import pytest
from PIL import Image

from app.cli import run
from models.bench.plot import Point, draw_speed_vs_error, pareto_front
from models.bench.system import PeakMemory
from models.networks.checkpoint import load_model
from models.networks.shipped import shipped_weights


def test_quick_bench_writes_json_report_and_figure(tmp_path):
    """The CI-sized run (about 15 s on an idle 2-core CPU: one scene, 1 and 4 spp, compact networks)."""
    report, numbers = tmp_path / "benchmarks.md", tmp_path / "benchmarks.json"
    assert run(["bench", "--quick", "--report", str(tmp_path)]) == 0
    results = json.loads(numbers.read_text())
    for key in ("nvrplus_light_edit_ms", "nvrplus_frame_ms", "pathtrace_1spp_oidn_ms", "shader_frame_ms",
                "shader_light_edit_ms", "shader_fast_frame_ms", "shader_fast_light_edit_ms"):
        assert math.isfinite(results[key]) and results[key] > 0.0
    # A light edit reruns only the stages after the light enters (timings are the benchmark's business,
    # not a test's): the last one, and the shader's light stages (or the lit floor) and the splat branch for
    # a model that reads them.
    shipped = load_model(shipped_weights("nvr_plus"))[1]
    first = ["shade_floor", "shade_lighting"] if shipped.shading_input else ["floor_light"] if shipped.floor_light_input else []
    expected = [*first, "splat_branch", "light"] if first else ["light"]
    assert results["edits"]["light"]["stages"] == expected
    # A move, a turn and a camera tilt keep the shader's voxel work (its geometry is the object's own voxels, placed).
    if shipped.shading_input:
        for edit in ("object move", "object turn", "camera"):
            assert "shade_surface" in results["edits"][edit]["stages"]
            assert "shade_geometry" not in results["edits"][edit]["stages"]
    labels = {row["label"] for row in results["renderers"]}
    assert {"path tracing 1 spp", "path tracing 1 spp + OIDN", "path tracing 4 spp + OIDN", "splatting"} <= labels
    rows = {row["label"]: row for row in results["renderers"]}
    # Denoising a 1-spp image brings it far closer to the reference than the raw samples.
    assert rows["path tracing 1 spp + OIDN"]["mse"] < rows["path tracing 1 spp"]["mse"] / 10
    assert set(results["pareto_front"]) <= labels
    assert all(n["gflop_frame"] > n["gflop_light_edit"] > 0 for n in results["networks"])
    text = report.read_text()
    assert "| path tracing | 1 spp + OIDN |" in text and "## Latency per edit" in text
    assert "- Voxel shader (256^3 grid, fast): a frame after an object move" in text
    # The shipped NVR+ in fp32 at both shader qualities, timed in turn with path tracing (one round when quick).
    shares = results["in_turn"]["shares"]
    assert set(shares) == {"full", "fast"} and all(len(v) == 1 and 0.0 < v[0] < 100.0 for v in shares.values())
    assert set(results["in_turn"]["rows"].values()) <= labels and "timed in turn (1 round;" in text
    # Under environment light: path tracing, the shader and NVR+ on the same scenes, and each environment edit.
    environment = results["environment"]
    assert [r["family"] for r in environment["rows"]][-2:] == ["voxel shader", "NVR+"]
    by_setting = {r["setting"]: r for r in environment["rows"] if r["family"] == "path tracing"}
    assert by_setting["1 spp + OIDN"]["mse"] < by_setting["1 spp"]["mse"] / 10
    for times in environment["edits"].values():
        assert set(times) == {"environment turn", "sun move", "strength", "material", "object move"}
        assert all(math.isfinite(ms) and ms > 0.0 for ms in times.values())
    assert "## Under environment light" in text and "- NVR+ object move: " in text
    # Against the number of objects (1 and 2 when quick): each renderer's three edits.
    counted = {(row["renderer"], row["objects"]) for row in results["objects"]}
    assert counted == {(r, n) for r in ("NVR+", "voxel shader") for n in (1, 2)}
    assert all(math.isfinite(ms) and ms > 0.0 for row in results["objects"] for ms in row["ms"].values())
    assert "## Against the number of objects" in text and "- Moving one object, 1 to 2 objects: " in text
    with Image.open(tmp_path / "speed_vs_error.png") as figure:
        assert figure.format == "PNG" and figure.width == 1100 and figure.height >= 760  # taller with a key


def test_quick_bench_never_writes_the_project_page(tmp_path, capsys):
    """A --quick run's one-scene numbers stay out of docs/, and an earlier report is kept without --force."""
    from models.bench.benchmark import DOCS

    page = DOCS / "benchmarks.md"
    before = page.read_bytes()
    assert run(["bench", "--quick", "--report", str(DOCS)]) == 2
    assert "--quick" in capsys.readouterr().err
    assert page.read_bytes() == before
    (tmp_path / "benchmarks.md").write_text("earlier report")
    assert run(["bench", "--quick", "--report", str(tmp_path)]) == 2
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "benchmarks.md").read_text() == "earlier report"


@pytest.mark.parametrize("native_bf16", [False, True])
def test_a_cpu_with_native_bfloat16_keeps_its_own_page_in_the_docs(tmp_path, monkeypatch, native_bf16):
    # The docs hold the page of the CPU without bfloat16 (the targets' CPU) and one of a CPU with it: a run on the
    # latter writes its own files there and never replaces the former; elsewhere the names stay plain.
    from models.bench import benchmark
    from models.engine import onednn

    monkeypatch.setattr(onednn, "cpu_has_native_bfloat16", lambda: native_bf16)
    monkeypatch.setattr(benchmark, "DOCS", tmp_path.resolve())
    names = [p.name for p in benchmark.report_files(tmp_path)]
    suffix = "_avx512_bf16" if native_bf16 else ""
    assert names == [f"benchmarks{suffix}.md", f"benchmarks{suffix}.json", f"speed_vs_error{suffix}.png"]
    assert [p.name for p in benchmark.report_files(tmp_path / "elsewhere")] == list(benchmark.REPORT_FILES)


def test_the_pareto_target_is_judged_on_the_shares_timed_in_turn():
    from models.bench.report import _in_turn

    rival = {"label": "path tracing 1 spp + OIDN", "mse": 7.0}
    rows = [{"label": "NVR+ a", "mse": 9.0}, {"label": "NVR+ b", "mse": 12.0}, rival]
    results = {"renderers": rows, "in_turn": {"rows": {"full": "NVR+ a", "fast": "NVR+ b"},
                                              "shares": {"full": [0.5, 0.4, 0.45], "fast": [0.3, 0.4, 0.32]}}}
    line = _in_turn(results, rival)[0]
    assert "full quality a median 0.450 of its time (0.400-0.500 by round)" in line and "(3 rounds;" in line
    assert line.endswith("met at the fast quality.")  # median 0.32 <= 1/3, MSE 12 <= 3 x 7
    results["in_turn"]["shares"]["fast"] = [0.3, 0.4, 0.35]
    assert _in_turn(results, rival)[0].endswith("missed.")  # median 0.35
    rows[1]["mse"] = 21.5  # over three times path tracing's
    results["in_turn"]["shares"]["fast"] = [0.2]
    assert _in_turn(results, rival)[0].endswith("missed.")
    assert _in_turn({"renderers": rows, "in_turn": None}, rival) == []


def test_the_shader_budgets_are_judged_at_both_qualities():
    """The voxel shader's budgets (30 ms a frame after a move, 10 ms a light edit) at its full and its fast quality,
    each judged on its own numbers; a report from before the fast quality's numbers has the full quality's line only."""
    from models.bench.report import _targets

    results = {"renderers": [{"label": "path tracing 1 spp + OIDN", "family": "path tracing", "mse": 7.0, "ms": 150.0}],
               "pareto_front": [], "edits": {name: {"ms": 20.0} for name in ("light", "object move", "camera")},
               "shader_grid": "256^3 grid", "shader_frame_ms": 36.6, "shader_light_edit_ms": 9.5,
               "shader_fast_frame_ms": 21.3, "shader_fast_light_edit_ms": 10.5}
    lines = [line for line in _targets(results) if line.startswith("- Voxel shader")]
    assert lines == ["- Voxel shader (256^3 grid): a frame after an object move 36.6 ms (target 30 ms: missed), "
                     "a light edit 9.5 ms (target 10 ms: met).",
                     "- Voxel shader (256^3 grid, fast): a frame after an object move 21.3 ms (target 30 ms: met), "
                     "a light edit 10.5 ms (target 10 ms: missed)."]
    del results["shader_fast_frame_ms"], results["shader_fast_light_edit_ms"]
    assert [line for line in _targets(results) if line.startswith("- Voxel shader")] == lines[:1]


def test_rows_are_timed_in_step_scene_by_scene():
    """Every contender renders a scene (its image, untimed, in the first round only) and is timed on it before any
    moves on to the next scene, in turn forwards and backwards, the scenes over again each round; only a contender
    that asks for it has its light edit timed."""
    from models.bench.benchmark import BenchSettings, Contender, bench_in_step
    from models.bench.scenes import BenchScene
    from renderer.scene import ObjectSpec, Scene

    calls = []

    class Recorder:
        def __init__(self, name, bench):
            self.name, self.bench = name, bench

        def render(self, scene):
            calls.append((self.name, self.bench))
            return np.zeros((2, 2, 3), dtype=np.float32)

    class Fake(Contender):
        def __init__(self, name, light_edit):
            super().__init__()
            self.name, self.light_edit = name, light_edit

        def renderer_for(self, bench):
            return Recorder(self.name, bench.name)

        def row(self, score):
            raise AssertionError("not called")

    class NoMemory:
        def start(self):
            pass

        def peak_mb(self):
            return 1.0

    contenders = [Fake("a", True), Fake("b", False)]
    scene = Scene.single(object=ObjectSpec(voxels="box.npz"))
    scenes = [BenchScene(name, scene, None) for name in ("s0", "s1", "s2")]
    settings = BenchSettings(repeats=2, in_step_rounds=2)
    bench_in_step(contenders, scenes, settings, NoMemory())
    timed = 2 + settings.repeats  # alternating_ms renders the pair once each, then times
    a, b = timed * 2, timed  # renders per scene: "a" also times its light edit
    expected = []
    for round_ in range(2):
        for index, name in enumerate(("s0", "s1", "s2")):
            if round_ == 0:
                expected += [("a", name), ("b", name)]  # the untimed images
            runs = [("a", name)] * a + [("b", name)] * b
            expected += runs if (3 * round_ + index) % 2 == 0 else runs[::-1]
    assert calls == expected
    assert [len(c.images) for c in contenders] == [3, 3] and contenders[0].peak_mb == 1.0
    assert len(contenders[0].times) == len(contenders[0].light_times) == 2 * 3 * settings.repeats
    assert len(contenders[1].times) == 2 * 3 * settings.repeats and contenders[1].light_times == []


def test_a_cpu_without_bfloat16_has_its_own_pareto_front():
    """A float32 network that only its own bfloat16 run dominates is on the front of the rows a CPU without bfloat16
    runs (the targets' CPU), and the report says so in a column of its own; with no bfloat16 row there is one front."""
    from models.bench.benchmark import Row, pareto_labels
    from models.bench.report import _renderers, _targets

    rows = [Row("path tracing", "1 spp + OIDN", 120.0, 110.0, 130.0, 10.0, 7.0, 0.005, 4.0),
            Row("NVR+", "net, bf16", 30.0, 28.0, 32.0, 500.0, 8.8, 0.006, 5.7, precision="bf16"),
            Row("NVR+", "net, fp32", 40.0, 38.0, 42.0, 500.0, 8.9, 0.006, 5.7),
            Row("splatting", "", 60.0, 55.0, 65.0, 400.0, 2500.0, 0.07, 41.0)]
    assert pareto_labels(rows) == ["NVR+ net, bf16", "path tracing 1 spp + OIDN"]
    assert pareto_labels(rows, without_bf16=True) == ["NVR+ net, fp32", "path tracing 1 spp + OIDN"]
    results = {"renderers": [asdict(r) | {"label": r.label} for r in rows], "pareto_front": pareto_labels(rows),
               "pareto_front_without_bf16": pareto_labels(rows, without_bf16=True),
               "edits": {name: {"ms": 20.0} for name in ("light", "object move", "camera")}}
    table = "\n".join(_renderers(results))
    assert "| Pareto | Pareto without bf16 |" in table
    assert "| net, fp32 | 40.0 | 38.0–42.0 | 500 | 8.90 | 0.0060 | 5.700 |  | yes |" in table
    targets = "\n".join(_targets(results))
    assert "MSE 8.90; not on the Pareto front (on the front without bf16)." in targets
    assert "MSE 8.80; on the Pareto front. Against" in targets
    alone = [r for r in rows if r.precision == "fp32"]
    results |= {"renderers": [asdict(r) | {"label": r.label} for r in alone], "pareto_front": pareto_labels(alone),
                "pareto_front_without_bf16": pareto_labels(alone, without_bf16=True)}
    assert "without bf16" not in "\n".join(_renderers(results) + _targets(results))


def test_pareto_front_by_hand():
    points = [Point("a", "NVR+", 10, 50), Point("b", "path tracing", 100, 5), Point("c", "splatting", 5, 3000),
              Point("d", "path tracing", 200, 40), Point("e", "NVR", 10, 60)]
    # d is slower and worse than b; e ties a on time and is worse.
    assert [p.label for p in pareto_front(points)] == ["c", "a", "b"]


def test_figure_labels_overlap_nothing_and_crowded_points_are_keyed(tmp_path):
    from PIL import Image, ImageFont

    from models.bench.plot import HEIGHT, KEY_ROW, _place_labels

    font = ImageFont.load_default(size=14)
    apart = [(200.0, 300.0), (700.0, 150.0)]
    crowded = [(400.0 + k, 400.0 + k) for k in range(16)]  # sixteen points within 15 x 15 pixels
    points = [Point(f"renderer number {k}", "NVR+", 1.0, 1.0) for k in range(len(apart) + len(crowded))]
    placed = _place_labels(points, apart + crowded, font)
    assert [text for text, _, _ in placed[:2]] == ["renderer number 0", "renderer number 1"]
    numbers = [text for text, _, _ in placed[2:] if text.isdigit()]
    assert numbers == [str(k) for k in range(1, len(numbers) + 1)] and len(numbers) >= 3
    boxes = [(left, top, left + font.getlength(text), top + 16) for text, left, top in placed]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            assert not (a[0] < b[2] and a[2] > b[0] and a[1] < b[3] and a[3] > b[1])  # no two labels overlap
    draw_speed_vs_error([Point(f"renderer number {k}", "NVR+", 50 + 0.5 * k, 10 + 0.1 * k) for k in range(8)]
                        + [Point("far", "splatting", 5, 3000)], tmp_path / "f.png")
    image = Image.open(tmp_path / "f.png")
    assert image.height > HEIGHT and (image.height - HEIGHT - 10) % KEY_ROW == 0  # a key below for the numbers


def test_a_label_set_away_from_its_point_is_joined_to_it_by_a_line():
    from models.bench.plot import _leader

    assert _leader(100.0, 100.0, (109.0, 84.0, 200.0, 100.0)) is None  # beside it, just above and right
    assert _leader(100.0, 100.0, (0.0, 92.0, 91.0, 108.0)) is None  # beside it, left
    x0, y0, x1, y1 = _leader(100.0, 100.0, (80.0, 40.0, 160.0, 56.0))  # 44 px straight above
    assert (x0, y0, x1, y1) == pytest.approx((100.0, 94.0, 100.0, 56.0))  # from the circle's top to the box's bottom
    x0, y0, x1, y1 = _leader(0.0, 0.0, (30.0, 40.0, 90.0, 56.0))  # up and to the right: to the box's nearest corner
    assert (x1, y1) == (30.0, 40.0) and math.hypot(x0, y0) == pytest.approx(6.0)
    assert (x0, y0) == pytest.approx((6.0 * 30.0 / 50.0, 6.0 * 40.0 / 50.0))


def test_peak_memory_sees_a_native_allocation():
    memory = PeakMemory()
    memory.start()
    block = np.ones(50_000_000)  # 400 MB, touched
    del block
    assert memory.peak_mb() >= 380.0
    if memory.method.startswith("VmHWM"):  # the peak is reset per measurement
        memory.start()
        assert memory.peak_mb() < 50.0


def test_capture_bench_boxes_hold_the_object_within_the_stated_margin_and_every_style_is_drawn():
    from benchmarks.bench_capture import BOX_MARGIN, photo_list, user_box

    mask = np.zeros((100, 120), dtype=bool)
    mask[30:60, 2:50] = True  # near the left edge
    rng = np.random.default_rng(0)
    for _ in range(20):
        x0, y0, x1, y1 = user_box(mask, rng)
        assert x0 == 0  # clipped to the photo
        assert 30 - BOX_MARGIN[1] * 100 <= y0 <= 30 - BOX_MARGIN[0] * 100 + 1
        assert 60 + BOX_MARGIN[0] * 100 - 1 <= y1 <= 60 + BOX_MARGIN[1] * 100
        assert 50 + BOX_MARGIN[0] * 100 - 1 <= x1 <= 50 + BOX_MARGIN[1] * 100
    order = photo_list(8)
    assert [style for style, _ in order].count("floor") == 8 and [s for s, _ in order].count("real") == 8
    assert [s for s, _ in order].count("studio") == 2 and len(set(order)) == len(order)
    assert user_box(np.zeros((10, 10), dtype=bool), rng) is None


def test_the_device_bench_compares_images_on_the_0_255_scale():
    """bench_device's image check: a uniform offset of 2/255 on a quarter of the pixels is a largest difference
    of 2 and an MSE of 4 / 4 = 1; a NaN pixel is reported as not finite."""
    from benchmarks.bench_device import compare

    reference = np.full((8, 8, 3), 0.5, dtype=np.float32)
    image = reference.copy()
    image[:4, :4] += 2.0 / 255.0
    result = compare(image, reference)
    assert math.isclose(result["max_diff"], 2.0, rel_tol=1e-5) and math.isclose(result["mse"], 1.0, rel_tol=1e-4)
    assert result["finite"]
    image[0, 0, 0] = np.nan
    assert not compare(image, reference)["finite"]


def test_every_benchmark_script_imports():
    """The scripts under benchmarks/ run by hand, not in the suite: at least they must still import what they call."""
    import importlib
    from pathlib import Path

    scripts = sorted(Path(__file__).resolve().parents[1].glob("benchmarks/*.py"))
    assert len(scripts) > 5
    for script in scripts:
        if script.stem != "__init__":
            importlib.import_module(f"benchmarks.{script.stem}")
