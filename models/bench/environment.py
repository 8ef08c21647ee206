"""`nvr bench` under environment light: its scenes lit by a sun and sky alone (the area light off), each object glossy
(ceramic, metal, plastic in turn), and the environment edits timed on them (models/bench/benchmark.py runs them).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from renderer.scene import EnvironmentSpec, MaterialSpec, Scene, SkySpec

SKY = SkySpec(sun_elevation_deg=35.0, sun_azimuth_deg=120.0, turbidity=3.0)
# One per scene in turn: the editor's ceramic, metal and plastic presets.
MATERIALS = (MaterialSpec(0.12, 0.6, 0.0), MaterialSpec(0.25, 0.5, 1.0), MaterialSpec(0.35, 0.5, 0.0))
OTHER_MATERIAL = MaterialSpec(0.5, 0.5, 0.0)  # what a material edit switches to


def environment_scene(scene: Scene, index: int) -> Scene:
    """`scene` under the sky alone, its object in the index-th of MATERIALS."""
    return scene.with_changes(environment=EnvironmentSpec(sky=SKY), light=replace(scene.light, enabled=False),
                              object=replace(scene.object, material=MATERIALS[index % len(MATERIALS)]))


def describe(value: SkySpec | MaterialSpec) -> str:
    """A sky or a material in words, for the report."""
    if isinstance(value, SkySpec):
        return (f"sun at {value.sun_elevation_deg:g} degrees elevation and {value.sun_azimuth_deg:g} azimuth, "
                f"turbidity {value.turbidity:g}")
    return f"roughness {value.roughness:g}, specular {value.specular:g}, metallic {value.metallic:g}"


def sun_drag(scene: Scene, steps: int) -> list[Scene]:
    """`scene` with its sun moved 2 degrees in azimuth and 0.5 in elevation at each of `steps` steps, as a drag
    on the sun's hemisphere moves it: a drag through skies never seen before (alternating two skies would time the
    cache that keeps them; the azimuth alone turns one baked sky)."""
    env = scene.environment
    return [scene.with_changes(environment=replace(env, sky=replace(
        env.sky, sun_azimuth_deg=(env.sky.sun_azimuth_deg + 2.0 * (k + 1)) % 360.0,
        sun_elevation_deg=5.0 + (env.sky.sun_elevation_deg - 5.0 + 0.5 * (k + 1)) % 80.0))) for k in range(steps)]


def edit_pairs(scene: Scene) -> dict[str, tuple[Scene, Scene]]:
    """Two scenes per environment edit that differ only in it (the issue's targets name these; the sun's drag is
    sun_drag)."""
    env, o = scene.environment, scene.object
    return {
        "environment turn": (scene, scene.with_changes(environment=replace(env, rotation_deg=env.rotation_deg + 15.0))),
        "strength": (scene, scene.with_changes(environment=replace(env, strength=env.strength * 1.2))),
        "material": (scene, scene.with_changes(object=replace(o, material=OTHER_MATERIAL))),
        "object move": (scene, scene.with_changes(object=replace(o, translation=(o.translation[0] + 0.15,
                                                                                 o.translation[1] - 0.1)))),
    }


def edit_ms(renderer: Any, scene: Scene, repeats: int,
            alternating_ms: Callable[[Any, tuple[Scene, Scene], int], list[float]]) -> dict[str, list[float]]:
    """ms per render of each edit of edit_pairs (`alternating_ms`, as the bench times edits) and of a sun drag
    (sun_drag), of `renderer` (anything with render(scene) -> image) on `scene`."""
    times = {name: alternating_ms(renderer, pair, repeats) for name, pair in edit_pairs(scene).items()}
    renderer.render(scene)
    times["sun move"] = []
    for step in sun_drag(scene, repeats):
        start = time.perf_counter()
        renderer.render(step)
        times["sun move"].append((time.perf_counter() - start) * 1000.0)
    return times
