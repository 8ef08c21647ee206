"""docs/benchmarks.md from the numbers of one `nvr bench` run (models/bench/benchmark.py)."""

from __future__ import annotations

import statistics
from pathlib import Path
from typing import Any

from models.bench.objects import MOVE_GROWTH_TARGET, TARGETS_MS
from models.bench.objects import SCALE as OBJECT_SCALE
from models.renderers import RENDERERS
from renderer.io import atomic_path

LIGHT_TARGET_MS = 33.0  # 30 frames a second
MOVE_TARGET_MS = 80.0  # a full NVR+ frame while the object is dragged
EDIT_TARGET_MS = 100.0  # the paper's NVR+ time on a desktop GPU
SHADER_LIGHT_TARGET_MS = 10.0  # the shader's light-dependent part: it runs before the network's light stage
SHADER_FRAME_TARGET_MS = 30.0  # a whole shaded frame after an object move: the editor's drag preview
# Under environment light (the natural-light issue's targets): an environment edit (turn, sun, strength) with NVR+ and
# with the shader alone, an object move and a material change (NVR+); NVR+ against path tracing at 1 spp + OIDN.
ENVIRONMENT_EDIT_TARGET_MS = {"NVR+": 40.0, "voxel shader": 15.0}
ENVIRONMENT_MOVE_TARGET_MS = 90.0
MATERIAL_TARGET_MS = 60.0
PARETO_TIME_SHARE = 1.0 / 3.0  # NVR+ against path tracing at 1 spp + OIDN: at most this share of its time,
PARETO_MSE_FACTOR = 3.0  # for at most this many times its MSE
BUSY_SHARE = 0.05  # other processes' CPU time, as a share of the run's wall time, above which timings are inflated


def write_report(results: dict[str, Any], path: Path, figure: Path) -> None:
    lines = (_header(results) + _renderers(results) + _targets(results) + _edits(results) + _environment(results)
             + _objects(results))
    lines += _networks(results)
    lines += ["## Speed against error", "", f"![error against time]({figure.name})", "", *_method(results)]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def _header(r: dict[str, Any]) -> list[str]:
    load = r["load"]
    # The 1-minute load average lags (it still counts whatever ran just before) and counts this
    # run's own threads, so the CPU time other processes took during the run decides.
    others = sum(p["cpu_seconds"] for p in load["other_processes"])
    busy = others > BUSY_SHARE * r["seconds"]
    lines = [
        "# Benchmarks: speed against error",
        "",
        f"Written by `nvr bench{' --quick' if r['quick'] else ''}` on {r['date']} ({r['seconds']:.0f} s).",
        "",
    ]
    if busy:
        lines += ["**Measured on a busy machine: other processes shared the CPU (below), so times are inflated "
                  "and not final.**", ""]
    if r["note"]:
        lines += [r["note"], ""]
    lines += ["| machine | |", "|---|---|"] + [f"| {k} | {v} |" for k, v in r["machine"].items()]
    lines += [f"| peak memory | {r['memory_method']} |", ""]
    before, after = load["loadavg_before"], load["loadavg_after"]
    lines += [f"What else was running: load average {before[0]:.2f} at the start, {after[0]:.2f} at the end."]
    if load["other_processes"]:
        lines += ["Other processes that used CPU during the run:", ""]
        lines += [f"- {p['cpu_seconds']:.0f} CPU s: `{p['command']}`" for p in load["other_processes"]]
    else:
        lines += ["No other process used more than half a CPU second."]
    lines += ["", f"Scenes ({len(r['scenes'])}): {', '.join(r['scenes'])}. Reference: {r['reference_spp']} spp "
              f"path tracing, raw. Images {r['size']}x{r['size']}.", ""]
    return lines


def _front_without_bf16(r: dict[str, Any]) -> set[str] | None:
    """The Pareto front of the rows a CPU without bfloat16 runs, where bfloat16 rows were benched (else None: one front)."""
    if "pareto_front_without_bf16" not in r or not any(row.get("precision") == "bf16" for row in r["renderers"]):
        return None
    return set(r["pareto_front_without_bf16"])


def _renderers(r: dict[str, Any]) -> list[str]:
    front, no_bf16 = set(r["pareto_front"]), _front_without_bf16(r)
    extra = ("", "") if no_bf16 is None else (" Pareto without bf16 |", ":---:|")
    lines = ["## Renderers", "",
             "| renderer | setting | median ms / frame | IQR (ms) | peak MB | MSE (0-255) | DSSIM | perceptual | Pareto |"
             + extra[0], "|---|---|---:|---|---:|---:|---:|---:|:---:|" + extra[1]]
    for row in r["renderers"]:
        errors = ("—", "—", "—") if row["mse"] is None else (
            f"{row['mse']:.2f}", f"{row['dssim']:.4f}", f"{row['perceptual']:.3f}")
        line = (f"| {row['family']} | {row['setting']} | {row['ms']:.1f} | {row['ms_q25']:.1f}–{row['ms_q75']:.1f} "
                f"| {row['peak_mb']:.0f} | {' | '.join(errors)} | {'yes' if row['label'] in front else ''} |")
        if no_bf16 is not None:
            line += f" {'yes' if row['label'] in no_bf16 else ''} |"
        lines.append(line)
    if no_bf16 is not None:
        lines += ["", "Pareto without bf16: the front of the rows a CPU without bfloat16 runs (float32 networks and the "
                  "other renderers), the CPU the targets are set for."]
    return lines + [""]


def _shader_budget(setting: str, frame: float, light_edit: float) -> str:
    """The targets' line of the voxel shader at one setting: its frame after an object move and its light edit."""
    return (f"- Voxel shader ({setting}): a frame after an object move {frame:.1f} ms (target {SHADER_FRAME_TARGET_MS:.0f} "
            f"ms: {'met' if frame <= SHADER_FRAME_TARGET_MS else 'missed'}), a light edit {light_edit:.1f} ms (target "
            f"{SHADER_LIGHT_TARGET_MS:.0f} ms: {'met' if light_edit <= SHADER_LIGHT_TARGET_MS else 'missed'}).")


def _targets(r: dict[str, Any]) -> list[str]:
    edits = {k: v for k, v in r["edits"].items() if isinstance(v, dict)}
    light = edits["light"]["ms"]
    move = edits["object move"]["ms"]
    slowest = max((k for k in edits if k not in ("light", "object move")), key=lambda k: edits[k]["ms"])
    rival = next(row for row in r["renderers"] if row["label"] == "path tracing 1 spp + OIDN")
    lines = ["## Targets", "",
             f"- Light edit: {light:.1f} ms (target {LIGHT_TARGET_MS:.0f} ms): {'met' if light < LIGHT_TARGET_MS else 'missed'}.",
             f"- Object move: {move:.1f} ms (target {MOVE_TARGET_MS:.0f} ms): {'met' if move < MOVE_TARGET_MS else 'missed'}.",
             f"- Other edits: slowest is {slowest}, {edits[slowest]['ms']:.1f} ms (target {EDIT_TARGET_MS:.0f} ms): "
             f"{'met' if edits[slowest]['ms'] < EDIT_TARGET_MS else 'missed'}."]
    if "shader_frame_ms" in r:
        grid = r.get("shader_grid", "128^3 grid")
        lines.append(_shader_budget(grid, r["shader_frame_ms"], r["shader_light_edit_ms"]))
        if "shader_fast_frame_ms" in r:  # the quality the editor can shade with (`--quality fast`)
            lines.append(_shader_budget(f"{grid}, fast", r["shader_fast_frame_ms"], r["shader_fast_light_edit_ms"]))
    trained = [row for row in r["renderers"] if row["family"] == RENDERERS["nvr+"].label and row["mse"] is not None]
    no_bf16 = _front_without_bf16(r)
    for row in trained:
        on_front = row["label"] in r["pareto_front"]
        without = ("" if no_bf16 is None or row.get("precision") == "bf16" else
                   f" ({'on' if row['label'] in no_bf16 else 'not on'} the front without bf16)")
        lines.append(f"- NVR+ {row['setting']}: {row['ms']:.1f} ms per frame, MSE {row['mse']:.2f}; "
                     f"{'on' if on_front else 'not on'} the Pareto front{without}. Against path tracing 1 spp + OIDN "
                     f"({rival['ms']:.1f} ms, MSE {rival['mse']:.2f}): {rival['ms'] / row['ms']:.1f}x faster, "
                     f"MSE {row['mse'] - rival['mse']:+.2f}.")
    lines += _in_turn(r, rival)
    if not trained:
        lines.append("- NVR+ on the Pareto front: no trained NVR+ weights were given, so it has no error yet "
                     f"(rival: path tracing 1 spp + OIDN, {rival['ms']:.1f} ms, MSE {rival['mse']:.2f}).")
    return lines + [""]


def _in_turn(r: dict[str, Any], rival: dict[str, Any]) -> list[str]:
    """The Pareto target (within PARETO_MSE_FACTOR times path tracing's MSE at 1 spp + OIDN in PARETO_TIME_SHARE of its
    time or less) for the shipped NVR+ in fp32, its frames timed in turn with path tracing's."""
    in_turn = r.get("in_turn")
    if not in_turn:
        return []
    rows = {row["label"]: row for row in r["renderers"]}
    parts, met = [], []
    for name, shares in in_turn["shares"].items():
        share, mse = statistics.median(shares), rows[in_turn["rows"][name]]["mse"]
        parts.append(f"at the {name} quality a median {share:.3f} of its time ({min(shares):.3f}-{max(shares):.3f} by round), "
                     f"MSE {mse:.2f}")
        if share <= PARETO_TIME_SHARE and mse <= PARETO_MSE_FACTOR * rival["mse"]:
            met.append(name)
    rounds = len(next(iter(in_turn["shares"].values())))
    verdict = f"met at the {' and '.join(met)} quality" if met else "missed"
    return [f"- The shipped NVR+ in fp32 against path tracing at 1 spp + OIDN (MSE {rival['mse']:.2f}), timed in turn "
            f"({rounds} round{'s' * (rounds != 1)}; the rows above are timed apart from path tracing): {'; '.join(parts)}. Target within "
            f"{PARETO_MSE_FACTOR:.0f} times its MSE in a third of its time or less: {verdict}."]


def _edits(r: dict[str, Any]) -> list[str]:
    e = r["edits"]
    rows = {k: v for k, v in e.items() if isinstance(v, dict)}
    has_full = any("full_grid_ms" in v for v in rows.values())
    lines = ["## Latency per edit (live engine)", "",
             f"NVR+ {e['model']} on {e['scene']}; median ms of alternating between two scenes that differ in the edit. "
             "The voxel branch runs on the object's crop of the grid (share of the grid in the last column)"
             + ("; the full-grid columns time the same edit without the crop." if has_full else "."), ""]
    header = "| edit | median ms | IQR (ms) | voxel branch ms |" + (" full grid ms | full-grid voxel branch ms |" if has_full else "")
    lines += [header + " stages rerun | grid share |", "|---|---:|---|---:|" + ("---:|---:|" if has_full else "") + "---|---:|"]
    for name, v in rows.items():
        full = f" {v['full_grid_ms']:.1f} | {v['full_grid_voxel_branch_ms']:.1f} |" if has_full else ""
        share = "—" if v["grid_fraction"] is None else f"{v['grid_fraction']:.2f}"
        lines.append(f"| {name} | {v['ms']:.1f} | {v['ms_q25']:.1f}–{v['ms_q75']:.1f} | {v['voxel_branch_ms']:.1f} |{full} "
                     f"{', '.join(v['stages'])} | {share} |")
    return lines + [""]


def _environment(r: dict[str, Any]) -> list[str]:
    """The rows and edit latencies under environment light (models/bench/environment.py), with their targets."""
    e = r.get("environment")
    if not e:
        return []
    lines = ["## Under environment light", "",
             f"The same scenes under a sun and sky alone ({e['sky']}), the objects glossy in turn "
             f"({'; '.join(e['materials'])}); reference {e['reference_spp']} spp path tracing, raw. "
             "No network is trained for environment light yet: NVR+ shows the voxel shader's image.", "",
             "| renderer | setting | median ms / frame | MSE (0-255) | DSSIM | perceptual |", "|---|---|---:|---:|---:|---:|"]
    lines += [f"| {row['family']} | {row['setting']} | {row['ms']:.1f} | {row['mse']:.2f} | {row['dssim']:.4f} | "
              f"{row['perceptual']:.3f} |" for row in e["rows"]]
    names = list(next(iter(e["edits"].values())))
    lines += ["", "| edit | " + " | ".join(f"{label} ms" for label in e["edits"]) + " |",
              "|---|" + "---:|" * len(e["edits"])]
    lines += [f"| {name} | " + " | ".join(f"{by_edit[name]:.1f}" for by_edit in e["edits"].values()) + " |"
              for name in names]
    lines += ["", *_environment_targets(e), ""]
    return lines


def _objects(r: dict[str, Any]) -> list[str]:
    """Edit latencies against the number of objects (models/bench/objects.py), with the several-objects targets."""
    rows = r.get("objects")
    if not rows:
        return []
    edits = list(TARGETS_MS)
    lines = ["## Against the number of objects", "",
             f"Scenes of procedural objects of 200^3 voxels at scale {OBJECT_SCALE:g}; median ms of each edit from the "
             "unedited scene, rendered by the shipped NVR+ and by the voxel shader.", "", "| renderer | objects | " + " | ".join(edits) + " |", "|---|---:|" + "---:|" * len(edits)]
    lines += [f"| {row['renderer']} | {row['objects']} | " + " | ".join(f"{row['ms'][e]:.1f}" for e in edits) + " |"
              for row in rows]
    nvr = {row["objects"]: row["ms"] for row in rows if row["renderer"] == "NVR+"}
    lines.append("")
    if 4 in nvr:
        lines += [f"- NVR+ at 4 objects, {edit}: {nvr[4][edit]:.1f} ms (target {target:.0f}: "
                  f"{'met' if nvr[4][edit] <= target else 'missed'})." for edit, target in TARGETS_MS.items()]
    if 1 in nvr and max(nvr) > 1:
        most = max(nvr)
        growth = nvr[most]["move one object"] / nvr[1]["move one object"]
        lines.append(f"- Moving one object, 1 to {most} objects: {growth:.2f} times (target at most "
                     f"{MOVE_GROWTH_TARGET:g}: {'met' if growth <= MOVE_GROWTH_TARGET else 'missed'}).")
    return lines + [""]


def _environment_targets(e: dict[str, Any]) -> list[str]:
    def verdict(ms: float, target: float) -> str:
        return f"{ms:.1f} ms (target {target:.0f}: {'met' if ms <= target else 'missed'})"

    lines = []
    for label, target in ENVIRONMENT_EDIT_TARGET_MS.items():
        slowest = max(("environment turn", "sun move", "strength"), key=lambda k: e["edits"][label][k])
        lines.append(f"- {label}, slowest environment edit ({slowest}): {verdict(e['edits'][label][slowest], target)}.")
    lines.append(f"- NVR+ object move: {verdict(e['edits']['NVR+']['object move'], ENVIRONMENT_MOVE_TARGET_MS)}; "
                 f"material change: {verdict(e['edits']['NVR+']['material'], MATERIAL_TARGET_MS)}.")
    rival = next((row for row in e["rows"] if row["label"] == "path tracing 1 spp + OIDN"), None)
    nvr = next((row for row in e["rows"] if row["family"] == "NVR+"), None)
    if rival and nvr:
        share, better = nvr["ms"] / rival["ms"], nvr["mse"] < rival["mse"]
        lines.append(f"- NVR+ against path tracing at 1 spp + OIDN ({rival['ms']:.1f} ms, MSE {rival['mse']:.2f}): "
                     f"{share:.2f} of its time, MSE {nvr['mse']:.2f}. Target a third of its time or less with a lower "
                     f"MSE: {'met' if share <= PARETO_TIME_SHARE and better else 'missed'}.")
    return lines


def _networks(r: dict[str, Any]) -> list[str]:
    lines = ["## Compute per frame", "",
             f"fp32 matrix-multiply peak measured in this run: {r['matmul_peak_gflops']:.0f} GFLOP/s. Network alone "
             "(no resampling or splat), full 128^3 grid, batch 1, random weights, on the engine's inference copy in "
             "float32 (the renderers table also times bfloat16, where the CPU has it).", "",
             "| network | config | GFLOP / frame | ms / frame | share of peak | GFLOP / light edit | ms / light edit | share of peak |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for n in r["networks"]:
        lines.append(f"| {n['architecture']} | {n['config']} | {n['gflop_frame']:.2f} | {n['frame_ms']:.1f} | "
                     f"{n['frame_fraction_of_peak']:.0%} | {n['gflop_light_edit']:.2f} | {n['light_edit_ms']:.1f} | "
                     f"{n['light_fraction_of_peak']:.0%} |")
    return lines + [""]


def _method(r: dict[str, Any]) -> list[str]:
    return [
        "## How these were measured", "",
        "- Time per frame: median and interquartile range over all scenes and repeats, wall clock. Path tracing: "
        "sampling plus OIDN with the Mitsuba scene built once per scene (kernels compiled before timing). "
        "Splatting: the splat of already painted voxels. Voxel shader: its stages after an object move along the floor "
        "(its light edit: the light stage alone). NVR / NVR+: a re-render after an object move along the floor "
        "through the live engine (resampling, voxel branch on the object's crop, splat, shading); the mesh is "
        "voxelised once per scene. Networks run in the precision named in their row: bf16 (bfloat16, the "
        "engine's default where the CPU computes it natively) or fp32. The voxel shader's rows and the trained "
        "networks' are timed in step, scene by scene (all of them on one scene, then the next, in turn forwards and "
        f"backwards; {r.get('in_step_rounds', 1)} round(s) over the scenes), so that the rows they compare are timed in "
        "the same minutes; the other rows one after another.",
        f"- Peak memory: resident memory above the level before each renderer ({r['memory_method']}); for the rows "
        "timed in step, the most that one scene's first render took.",
        "- Errors: mean over scenes of MSE (0-255), DSSIM and the perceptual distance of models/evaluation/metrics.py against "
        f"the {r['reference_spp']}-spp reference, whose own noise is included. Networks with random weights are timed only.",
        "- Pareto front: no other renderer is both at least as fast and at least as accurate (MSE).",
    ]
