"""Procedural objects: determinism, the object box, watertightness, parameters, splits and appearances."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from renderer.errors import InputError
from renderer.objects import CATEGORIES, apply_appearance, generate_object, split_seeds
from renderer.objects.appearance import MAX_FACES, refine
from renderer.objects.demo import DEMO_PATH, write_demo
from renderer.objects.noise import gradient_noise, make_lattice, value_noise
from renderer.objects.textures import TEST_FAMILIES, TRAIN_FAMILIES, draw_texture, triplanar

SEEDS_PER_CATEGORY = 10


def extents(obj) -> np.ndarray:
    return obj.mesh.bounds[1] - obj.mesh.bounds[0]


def normalised(lengths) -> np.ndarray:
    """Extents in metres -> extents in the object box (longest side 1)."""
    lengths = np.asarray(lengths, dtype=float)
    return lengths / lengths.max()


@pytest.mark.parametrize("category", sorted(CATEGORIES))
def test_objects_stand_in_the_object_box_and_are_watertight(category):
    for seed in range(SEEDS_PER_CATEGORY):
        obj = generate_object(category, seed)
        v = obj.mesh.vertices
        assert np.isfinite(v).all()
        low, high = obj.mesh.bounds
        assert low[1] == pytest.approx(0.0, abs=1e-12)  # stands on the floor
        assert (high - low).max() == pytest.approx(1.0, abs=1e-12)  # longest side 1
        assert (low[0] + high[0]) / 2 == pytest.approx(0.0, abs=1e-12)  # centred on x
        assert (low[2] + high[2]) / 2 == pytest.approx(0.0, abs=1e-12)  # and on z
        assert low[0] >= -0.5 - 1e-12 and high[0] <= 0.5 + 1e-12 and high[1] <= 1.0 + 1e-12
        assert obj.face_labels.shape == (len(obj.mesh.faces),)
        assert obj.face_labels.min() >= 0 and obj.face_labels.max() < len(obj.part_names)
        assert obj.mesh.is_watertight and obj.mesh.is_winding_consistent and obj.mesh.volume > 0
        assert len(obj.mesh.split(only_watertight=False)) == 1, "parts must touch: one piece"
        assert 12 <= len(obj.mesh.faces) <= 10_000


@pytest.mark.parametrize("category", sorted(CATEGORIES))
def test_same_seed_same_object_and_different_seeds_differ(category):
    a, b, c = generate_object(category, 5), generate_object(category, 5), generate_object(category, 6)
    assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
    assert np.array_equal(a.mesh.faces, b.mesh.faces)
    assert np.array_equal(a.face_labels, b.face_labels)
    assert a.params == b.params
    assert a.params != c.params
    assert len(a.mesh.vertices) != len(c.mesh.vertices) or not np.allclose(a.mesh.vertices, c.mesh.vertices)


def test_train_and_test_seeds_are_disjoint():
    train, test = split_seeds("train", 5000), split_seeds("test", 5000)
    assert len(train) == len(test) == 5000
    assert not set(train.tolist()) & set(test.tolist())
    assert np.array_equal(split_seeds("train", 3), [0, 1, 2])
    with pytest.raises(InputError):
        split_seeds("validation", 3)


def test_bad_requests_raise_input_error():
    with pytest.raises(InputError, match="category"):
        generate_object("lamp", 0)
    with pytest.raises(InputError, match="seed"):
        generate_object("chair", -1)
    with pytest.raises(InputError, match="wings"):
        generate_object("chair", 0, {"wings": 2})
    with pytest.raises(InputError, match="back_style"):
        generate_object("chair", 0, {"back_style": "throne"})
    obj = generate_object("chair", 0)
    with pytest.raises(InputError, match="setting"):
        apply_appearance(obj, "shiny", 0, "train")
    with pytest.raises(InputError, match="split"):
        apply_appearance(obj, "single", 0, "val")


PLAIN_CHAIR = {
    "leg_style": "straight",
    "seat_shape": "rect",
    "arm_style": "none",
    "cushion": False,
    "stretchers": False,
}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_backless_chair_has_the_proportions_of_its_seat(seed):
    obj = generate_object("chair", seed, {**PLAIN_CHAIR, "back_style": "none"})
    p = obj.params
    # Straight legs stand inside the seat: the bounding box is the seat's width, height and depth.
    expected = normalised([p["seat_width"], p["seat_height"], p["seat_depth"]])
    assert np.allclose(extents(obj), expected, atol=1e-9)


@pytest.mark.parametrize("recline", [0.0, 15.0])
def test_reclined_panel_back_extends_up_and_back_as_computed(recline):
    obj = generate_object("chair", 3, {**PLAIN_CHAIR, "back_style": "panel", "recline_deg": recline})
    p = obj.params
    w, d, h, t = p["seat_width"], p["seat_depth"], p["back_height"], p["back_thickness"]
    a = math.radians(recline)
    # The panel stands on the seat (sunk 1 cm into it) flush with the rear edge, tilted about its lower edge.
    back_z = -d / 2 + t / 2
    top = p["seat_height"] - 0.01 + h * math.cos(a) + t / 2 * math.sin(a)
    rear = back_z - h * math.sin(a) - t / 2 * math.cos(a)
    expected = normalised([w, top, d / 2 - rear])
    assert np.allclose(extents(obj), expected, atol=1e-9)


def test_backless_chairs_are_lower_than_chairs_with_backs():
    for seed in range(4):
        low = generate_object("chair", seed, {"back_style": "none", "arm_style": "none"})
        tall = generate_object("chair", seed, {"back_style": "panel", "arm_style": "none"})
        # Height relative to the footprint: a back adds at least 25 cm above the seat.
        low_ratio = extents(low)[1] / max(extents(low)[0], extents(low)[2])
        tall_ratio = extents(tall)[1] / max(extents(tall)[0], extents(tall)[2])
        assert tall_ratio > low_ratio + 0.2


def test_chair_options_add_their_parts():
    def present(obj) -> set[str]:
        return {obj.part_names[i] for i in np.unique(obj.face_labels)}

    base = {**PLAIN_CHAIR, "back_style": "slats"}
    assert present(generate_object("chair", 7, base)) == {"seat", "back", "leg"}
    assert "cushion" in present(generate_object("chair", 7, {**base, "cushion": True}))
    assert "stretcher" in present(generate_object("chair", 7, {**base, "stretchers": True}))
    assert "arm" in present(generate_object("chair", 7, {**base, "arm_style": "open"}))
    assert "back" not in present(generate_object("chair", 7, {**base, "back_style": "none"}))


def test_table_and_sofa_proportions_match_their_parameters():
    table = generate_object("table", 4, {"leg_style": "straight", "top_shape": "rect", "shelf": False})
    p = table.params
    assert np.allclose(extents(table), normalised([p["width"], p["height"], p["width"] * p["depth_ratio"]]), atol=1e-9)

    sofa = generate_object(
        "sofa", 4, {"arm_style": "none", "base_style": "plinth", "recline_deg": 0.0, "chaise": "none"}
    )
    p = sofa.params
    expected = [
        p["seats"] * p["seat_unit_width"],
        p["seat_height"] + p["back_height"],
        p["seat_depth"] + p["back_thickness"],
    ]
    assert np.allclose(extents(sofa), normalised(expected), atol=1e-9)


def test_a_taller_stool_is_taller():
    low = generate_object(
        "stool",
        2,
        {"seat_height": 0.4, "leg_style": "straight", "seat_shape": "round", "footrest": "none", "cushion": False},
    )
    tall = generate_object(
        "stool",
        2,
        {"seat_height": 0.8, "leg_style": "straight", "seat_shape": "round", "footrest": "none", "cushion": False},
    )
    size = low.params["seat_size"]
    assert np.allclose(extents(low), normalised([size, 0.4, size]), atol=1e-9)
    assert np.allclose(extents(tall), normalised([size, 0.8, size]), atol=1e-9)


def test_single_setting_has_one_color_and_a_floor_color_per_seed():
    obj = generate_object("chair", 1)
    mesh, floor, info = apply_appearance(obj, "single", 11, "train")
    colors = mesh.visual.vertex_colors
    assert colors.dtype == np.uint8 and colors.shape == (len(mesh.vertices), 4)
    assert len(np.unique(colors, axis=0)) == 1
    assert np.array_equal(colors[0, :3], np.round(np.array(info["color"]) * 255))
    assert colors[0, 3] == 255
    assert all(0.0 <= c <= 1.0 for c in floor)
    _, floor_again, _ = apply_appearance(obj, "default", 11, "train")
    _, other_floor, _ = apply_appearance(obj, "single", 12, "train")
    assert floor_again == floor and other_floor != floor


def test_default_setting_colors_parts_with_materials():
    obj = generate_object("chair", 8)
    mesh, _, info = apply_appearance(obj, "default", 8, "train")
    again, _, _ = apply_appearance(obj, "default", 8, "train")
    assert np.array_equal(mesh.visual.vertex_colors, again.visual.vertex_colors)
    assert set(info["materials"]) == {obj.part_names[i] for i in np.unique(obj.face_labels)}
    assert (mesh.visual.vertex_colors[:, 3] == 255).all()
    assert len(np.unique(mesh.visual.vertex_colors, axis=0)) > 50  # grain and weave, not flat paint
    assert mesh.is_watertight


def test_textured_families_are_split_and_the_mesh_is_refined():
    assert not set(TRAIN_FAMILIES) & set(TEST_FAMILIES)
    for split, families in (("train", TRAIN_FAMILIES), ("test", TEST_FAMILIES)):
        drawn = {draw_texture(np.random.default_rng(seed), split)[0] for seed in range(40)}
        assert drawn == set(families)  # every family of the split is used, none of the other
    obj = generate_object("stool", 3)
    for split, families in (("train", TRAIN_FAMILIES), ("test", TEST_FAMILIES)):
        mesh, _, info = apply_appearance(obj, "textured", 0, split)
        assert info["family"] in families
        assert mesh.is_watertight and info["faces"] == len(mesh.faces) <= MAX_FACES
        assert np.median(mesh.edges_unique_length) <= 0.0101
        assert np.allclose(mesh.bounds, obj.mesh.bounds, atol=1e-9)  # refinement moves no vertex off the surface
        assert len(np.unique(mesh.visual.vertex_colors, axis=0)) > 1


def test_every_texture_family_gives_varied_colors_in_range():
    uv = np.random.default_rng(0).uniform(-0.5, 0.5, size=(4000, 2))
    for name, family in {**TRAIN_FAMILIES, **TEST_FAMILIES}.items():
        colors = family(np.random.default_rng(3))(uv)
        assert colors.shape == (4000, 3) and np.isfinite(colors).all(), name
        assert colors.min() >= 0.0 and colors.max() <= 1.0, name
        assert colors.std(axis=0).max() > 0.05, name


def test_refinement_keeps_each_part_area_and_respects_the_face_cap():
    obj = generate_object("chair", 2)
    for cap in (MAX_FACES, 20_000):
        fine = refine(obj, 0.01, max_faces=cap)
        assert len(fine.mesh.faces) <= cap
        before = np.bincount(obj.face_labels, obj.mesh.area_faces, minlength=len(obj.part_names))
        after = np.bincount(fine.face_labels, fine.mesh.area_faces, minlength=len(obj.part_names))
        assert np.allclose(before, after, atol=1e-9)


def test_triplanar_on_an_axis_facing_surface_is_the_plain_projection():
    def texture(uv):
        return np.column_stack([uv[:, 0], uv[:, 1], np.zeros(len(uv))])

    points = np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    facing_z = triplanar(texture, points, np.array([[0.0, 0.0, 1.0]] * 2))
    facing_x = triplanar(texture, points, np.array([[-1.0, 0.0, 0.0]] * 2))
    assert np.allclose(facing_z, [[0.1, 0.2, 0], [0.4, 0.5, 0]], atol=1e-5)
    assert np.allclose(facing_x, [[0.3, 0.2, 0], [0.6, 0.5, 0]], atol=1e-5)


def test_noise_hits_its_lattice_values_and_stays_in_range():
    lattice = make_lattice(np.random.default_rng(0), 2)
    cells = np.array([[0, 0], [3, -2], [-7, 5]])
    expected = lattice.values[lattice.hash(cells)]
    assert np.allclose(value_noise(lattice, cells.astype(float)), expected)
    assert np.allclose(gradient_noise(lattice, cells.astype(float)), 0.5)  # gradient noise is zero at lattice points
    samples = np.random.default_rng(1).uniform(-20, 20, size=(2000, 2))
    for noise in (value_noise, gradient_noise):
        n = noise(lattice, samples)
        assert n.min() >= 0.0 and n.max() <= 1.0 and n.std() > 0.05


def test_demo_asset_is_what_the_demo_code_writes_and_keeps_its_colors(tmp_path):
    written = write_demo(tmp_path / "chair.obj")
    assert written.read_bytes() == DEMO_PATH.read_bytes()
    assert DEMO_PATH.stat().st_size < 3_000_000
    mesh = trimesh.load(DEMO_PATH, process=False)
    assert mesh.visual.kind == "vertex" and mesh.is_watertight
    colors = mesh.visual.vertex_colors
    assert len(np.unique(colors[:, :3], axis=0)) > 50
    assert mesh.bounds[0][1] == pytest.approx(0.0, abs=1e-7) and (mesh.extents.max() == pytest.approx(1.0, abs=1e-7))


def test_a_hollow_solid_keeps_its_outline_and_loses_volume():
    plain = {"layout_seed": 7, "size": 0.5, "pieces": 1, "cuts": 0, "rods": 0, "rod_radius": 0.01}
    full = generate_object("solids", 0, {**plain, "hollow": False})
    hollow = generate_object("solids", 0, {**plain, "hollow": True})
    assert np.allclose(full.mesh.bounds, hollow.mesh.bounds, atol=1e-9)  # the walls stand where the solid stood
    assert hollow.mesh.volume < 0.9 * full.mesh.volume


def test_a_tree_of_rods_is_thin_and_one_piece():
    rods = generate_object("solids", 0, {"layout_seed": 3, "pieces": 0, "rod_radius": 0.005})
    low, high = rods.mesh.bounds
    assert rods.mesh.volume < 0.05 * np.prod(high - low)  # thin parts: little of its box is filled
    assert len(rods.mesh.split(only_watertight=False)) == 1
