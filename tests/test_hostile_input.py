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
