"""Hostile and broken input on the command line and at the editor's start (generator: tests/hostile_inputs.py).

Every case must end with exit code 2 and exactly one line on the terminal naming the problem, no
traceback, under 1 GB of memory, with nothing written and no code run from a file.
"""

from __future__ import annotations

import shutil
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from tests.hostile_inputs import Case, Outcome, all_cases, run_case

CASES = all_cases()
MEMORY_BOUND_MB = 1024


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory, request) -> dict[str, Outcome]:
    """Every case run once, two at a time (the machine has two cores), each in a folder of its own."""
    display = request.getfixturevalue("display") if shutil.which("Xvfb") else None

    def run(indexed: tuple[int, Case]) -> tuple[str, Outcome | None]:
        index, case = indexed
        if case.program != "nvr" and display is None:
            return case.name, None
        folder = tmp_path_factory.mktemp(f"case{index}")
        return case.name, run_case(case, Path(folder), display)

    with ThreadPoolExecutor(2) as pool:
        return dict(pool.map(run, enumerate(CASES)))


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_hostile_input_is_refused_in_one_line_within_bounded_memory(case: Case, outcomes):
    outcome = outcomes[case.name]
    if outcome is None:
        pytest.skip("the editor's cases need Xvfb")
    lines = [line for line in (outcome.stdout + outcome.stderr).splitlines() if line.strip()]
    assert outcome.code == 2, lines[-5:]
    assert len(lines) == 1, lines[:5]
    assert "error" in lines[0] or case.program != "nvr", lines[0]
    assert "Traceback" not in outcome.stderr
    assert outcome.peak_rss_mb < MEMORY_BOUND_MB
    assert outcome.written == []  # nothing written, nothing half-written, no PWNED from the disguised pickle


# --- scene files: every key mutated in type and value ----------------------------------------------------

MUTATIONS = [None, True, 0, -1, 1e308, -1e308, 10**40, 0.5, "", "x\ud800", "a" * 5000, [], [1, 2], {}, {"a": 1},
             [[[[]]]], "nan", [float("nan")] * 3, [1e308] * 3, [-0.0] * 3]


def _key_paths(value, prefix=()):
    yield prefix
    if isinstance(value, dict):
        for key, item in value.items():
            yield from _key_paths(item, (*prefix, key))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from _key_paths(item, (*prefix, index))


def _mutated(data, path, value):
    import copy

    if not path:
        return value
    out = copy.deepcopy(data)
    target = out
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return out


def test_every_key_of_a_scene_mutated_gives_a_scene_or_a_one_line_refusal(tmp_path):
    """Each key of a full scene file (paint included) replaced by each hostile value, read in-process:
    the reader returns a valid scene or raises InputError with one line naming the file; nothing else."""
    import json

    from renderer.errors import InputError
    from renderer.io import parse_json
    from renderer.scene import scene_from_dict, validate

    base = {"version": 1, "object": {"mesh": "chair.obj", "up": "y", "resolution": 100, "color": [0.5, 0.5, 0.5],
                                     "translation": [0.1, -0.2], "rotation_deg": 30, "scale": [1, 1, 1]},
            "floor": {"color": [0.5, 0.6, 0.7]}, "light": {"position": [1.0, 2.75, 0.5]},
            "camera": {"elevation_deg": 30}, "image_size": 256,
            "paint": [{"target": "region", "color": [1, 0, 0], "seed": [50, 50, 50], "tolerance": 0.1},
                      {"target": "floor", "color": [0, 1, 0]}]}
    outcomes = {"accepted": 0, "refused": 0}
    for path in _key_paths(base):
        for value in MUTATIONS:
            data = _mutated(base, path, value)
            text = json.dumps(data, allow_nan=True)  # NaN and Infinity as a careless writer would put them
            try:
                scene = scene_from_dict(parse_json(text, "mutated.json"), "mutated.json")
            except InputError as exc:
                message = str(exc)
                assert message.startswith("mutated.json: ") and "\n" not in message, (path, value, message)
                outcomes["refused"] += 1
            else:
                validate(scene)
                outcomes["accepted"] += 1
    assert outcomes["refused"] > 300 and outcomes["accepted"] > 20  # both outcomes are exercised
