"""The one stage cache: a stage computes once per key, and reports what it computed."""

from __future__ import annotations

from renderer.stage_cache import StageCache


def counting(calls: list[str], name: str, value):
    def compute():
        calls.append(name)
        return value

    return compute


def test_a_stage_computes_once_per_key_and_reports_only_what_it_computed():
    cache, calls = StageCache(), []
    assert cache("a", 1, counting(calls, "a", "x")) == "x"
    cache.begin()
    assert cache("a", 1, counting(calls, "a", "y")) == "x"  # same key: kept
    assert cache.stage_ms == {} and calls == ["a"]
    assert cache("a", 2, counting(calls, "a", "z")) == "z"  # another key: computed again, timed
    assert list(cache.stage_ms) == ["a"] and cache.stage_ms["a"] >= 0.0
    assert cache.cached("a", 2) and not cache.cached("a", 1) and not cache.cached("b", 2)


def test_a_result_not_kept_leaves_the_kept_one():
    cache, calls = StageCache(), []
    cache("a", 1, counting(calls, "a", "live"))
    assert cache("a", 2, counting(calls, "a", "one-off"), keep=False) == "one-off"
    assert cache.cached("a", 1) and cache.last("a") == "live"
    assert cache("a", 1, counting(calls, "a", "again")) == "live" and calls == ["a", "a"]


def test_forget_and_clear_drop_results_and_settle_runs_after_each_computation():
    settled = []
    cache = StageCache(settle=lambda: settled.append(True))
    cache("a", 1, lambda: "x")
    cache("b", 1, lambda: "y")
    cache("b", 1, lambda: "not run")
    assert settled == [True, True]
    cache.forget("a")
    assert cache.last("a") is None and cache.last("b") == "y"
    cache.forget("missing")  # nothing to drop: no error
    cache.clear()
    assert not cache.cached("b", 1)
