"""The renderer table: every renderer by its one name draws, bit for bit, what its own functions draw."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from app.cli import build_parser
from models.engine.render_engine import RenderEngine
from models.renderers import (
    EVALUATED,
    INTERACTIVE,
    RENDERERS,
    RendererOptions,
    fixed_size,
    make_renderer,
    renderer_entry,
)
from renderer.errors import InputError
from renderer.pathtrace.path_tracer import render_pathtraced
from renderer.pipeline import object_voxels, painted_voxels
from renderer.reference_object import reference_scene
from renderer.scene import CameraSpec, LightSpec, PaintOp, Scene
from renderer.shading import FAST_QUALITY, FULL_QUALITY, shade_scene
from renderer.splat import splat_scene

ROOT = Path(__file__).resolve().parents[1]
# Each edit keeps some of a renderer's cached stages: the cached image must still be the one drawn from scratch.
EDITS = {
    "light": lambda s: s.with_changes(light=LightSpec((-0.8, 2.6, 1.2))),
    "move": lambda s: s.with_changes(object=replace(s.object, translation=(0.2, -0.1))),
    "paint": lambda s: s.with_changes(paint=(PaintOp("region", (0.0, 1.0, 0.0), seed=(5, 11, 5)),)),
    "camera": lambda s: s.with_changes(camera=CameraSpec(40.0)),
}


@pytest.fixture
def scene(two_color_box) -> Scene:
    return two_color_box


def _painted(scene: Scene):
    return painted_voxels(scene, object_voxels(scene))


@pytest.mark.parametrize("quality", ["full", "fast"])
def test_the_shader_by_name_is_shade_scene_through_every_edit(scene, quality):
    shader = make_renderer("shaded", RendererOptions(quality=quality))
    expected_quality = FULL_QUALITY if quality == "full" else FAST_QUALITY
    for edited in [scene, *(edit(scene) for edit in EDITS.values())]:
        expected = shade_scene(edited, *_painted(edited), quality=expected_quality).image
        np.testing.assert_array_equal(shader.render(edited), expected)
        np.testing.assert_array_equal(shader.render_sized(edited, 40), shade_scene(
            edited, *_painted(edited), size=40, quality=expected_quality).image)


def test_the_splat_by_name_is_splat_scene(scene):
    splat = make_renderer("splat")
    for edited in [scene, EDITS["paint"](scene), EDITS["move"](scene)]:
        np.testing.assert_array_equal(splat.render(edited), splat_scene(edited, *_painted(edited)))
        np.testing.assert_array_equal(splat.render_sized(edited, 40), splat_scene(edited, *_painted(edited), size=40))


def test_the_path_tracer_by_name_traces_the_painted_reference(scene):
    tracer = make_renderer("pathtrace", RendererOptions(spp=2, seed=3, denoise=False))
    for edited in [EDITS["paint"](scene), EDITS["light"](EDITS["paint"](scene))]:  # the second keeps the colored mesh
        reference, mesh = reference_scene(edited)
        expected = render_pathtraced(reference, mesh, size=24, spp=2, seed=3).image
        np.testing.assert_array_equal(tracer.render_sized(edited, 24), expected)


def test_the_network_by_name_is_the_engine_of_its_weights(scene, refiner_file):
    network = make_renderer("nvr+", RendererOptions(model=str(refiner_file), precision="fp32", device="cpu"))
    direct = RenderEngine.load(refiner_file, precision="fp32", device="cpu")
    assert fixed_size(network) is None  # it corrects the shader's image: any size
    for edited in [scene, *(edit(scene) for edit in EDITS.values())]:
        np.testing.assert_array_equal(network.render(edited), direct.render(edited))
    np.testing.assert_array_equal(network.render_sized(scene, 40), direct.render_sized(scene, 40))
    with pytest.raises(InputError, match="not nvr"):
        make_renderer("nvr", RendererOptions(model=str(refiner_file)))


def test_the_names_are_the_commands_choices_and_unknown_names_are_refused():
    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices  # argparse keeps each command's parser here
    choices = {name: next(a.choices for a in commands[name]._actions if a.dest == "renderer")
               for name in ("render", "turntable", "eval")}
    assert choices == {"render": list(RENDERERS), "turntable": list(RENDERERS), "eval": list(EVALUATED)}
    assert "pathtrace" not in EVALUATED and set(INTERACTIVE) == {"nvr+", "shaded"}
    with pytest.raises(InputError, match="unknown renderer 'nvr_plus'"):
        renderer_entry("nvr_plus")


def test_no_renderer_name_is_switched_on_outside_the_table():
    """`renderer == "splat"` and the like: each such switch is a place a new renderer would have to be written into."""
    names = "|".join(re.escape(name) for name in RENDERERS)
    switch = re.compile(rf"""(==|!=|\bin\b)\s*\(?["']({names})["']|["']({names})["']\s*(==|!=)""")
    found = []
    for path in [*ROOT.glob("app/**/*.py"), *ROOT.glob("models/**/*.py"), *ROOT.glob("renderer/**/*.py")]:
        if path.name == "renderers.py":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if switch.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
