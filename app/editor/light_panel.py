"""The lighting and the floor of the Light & camera tab (area light, sun and sky, environment image; floor color or
texture) and the Object tab's material.

GUI functions over the Interface (app/editor/panels.py): each change previews while a slider is held and is one undo
step when it is let go, as every field of the tools.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

import moderngl
from imgui_bundle import imgui

from app.editor import edits
from app.editor.file_dialog import FileKind
from app.editor.photo_panel import GRAY
from app.editor.window import upload_image
from renderer.environment import environment_light, environment_thumbnail
from renderer.errors import InputError
from renderer.scene import FLOOR_SHAPES, MaterialSpec, Scene, SkySpec


class Interface(Protocol):
    """What these functions use of the tools' Interface (app/editor/panels.py)."""

    app: Any  # the EditorApp
    fields: Any  # the path fields (panels.Fields)
    environment_preview: EnvironmentPreview

    def edit_field(self, key: str, changed: bool, make_scene: Callable[[Scene], Scene], of_object: bool = False) -> None: ...

    def browse_button(self, key: str, kind: FileKind, field_name: str) -> None: ...

ENVIRONMENT_FILES = FileKind("Load an environment", "Environment maps", ("*.hdr", "*.exr", "*.png", "*.jpg", "*.jpeg"))
TEXTURE_FILES = FileKind("Load a floor texture", "Images", ("*.png", "*.jpg", "*.jpeg"))
LIGHTING = ("area light and ambient", "sun and sky", "environment image")
SUN_WIDGET_SIDE = 150  # pixels: the sun's hemisphere seen from above


def draw_lighting(ui: Interface) -> None:
    """Which light, and its settings."""
    app, scene = ui.app, ui.app.scene
    env = scene.environment
    kind = 0 if env is None else (1 if env.sky is not None else 2)
    changed, chosen = imgui.combo("lighting", kind, list(LIGHTING))
    if changed and chosen != kind:
        if chosen == 0:
            app.edit(lambda s: edits.set_environment(s, None))
        elif chosen == 1:
            app.edit(edits.use_sky)
        elif ui.fields.environment_path:
            load_environment(ui)
        else:
            app.say("type or browse to an environment image below, then press Load")
            ui.fields.show_environment_field = True
    if env is None:
        _area_light_position(ui)
        if not ui.fields.show_environment_field:
            return
    else:
        changed, on = imgui.checkbox("area light too", scene.light.enabled)
        if changed:
            app.edit(lambda s: edits.switch_area_light(s, on))
        if scene.light.enabled:
            _area_light_position(ui)
    if env is not None and env.sky is not None:
        sky = env.sky
        _sun_hemisphere(ui, sky)
        imgui.same_line()
        ui.environment_preview.draw(ui)
        changed, elevation = imgui.slider_float("sun elevation", sky.sun_elevation_deg, 0.0, 90.0, "%.1f deg")
        ui.edit_field("sun elevation", changed, lambda s: edits.set_sky(s, elevation, sky.sun_azimuth_deg, sky.turbidity))
        changed, azimuth = imgui.slider_float("sun azimuth", sky.sun_azimuth_deg, -180.0, 180.0, "%.1f deg")
        ui.edit_field("sun azimuth", changed, lambda s: edits.set_sky(s, sky.sun_elevation_deg, azimuth, sky.turbidity))
        changed, turbidity = imgui.slider_float("haze (turbidity)", sky.turbidity, 1.0, 10.0, "%.1f")
        ui.edit_field("turbidity", changed, lambda s: edits.set_sky(s, sky.sun_elevation_deg, sky.sun_azimuth_deg,
                                                                turbidity))
    if env is None or env.image is not None:
        imgui.set_next_item_width(200)
        _, ui.fields.environment_path = imgui.input_text("##environment", ui.fields.environment_path)
        ui.browse_button("environment", ENVIRONMENT_FILES, "environment_path")
        imgui.same_line()
        if imgui.button("Load environment") and ui.fields.environment_path:
            load_environment(ui)
        imgui.text_colored(GRAY, ".hdr and .exr are linear light; .png and .jpg are read as sRGB (no highlights).")
    if env is not None:
        if env.sky is None:  # a sky's is beside its sun
            ui.environment_preview.draw(ui)
        changed, rotation = imgui.slider_float("turn environment", env.rotation_deg, -180.0, 180.0, "%.1f deg")
        ui.edit_field("environment turn", changed, lambda s: edits.turn_environment(s, rotation_deg=rotation))
        changed, strength = imgui.slider_float("strength", env.strength, 0.0, edits.MAX_STRENGTH, "%.2f",
                                               imgui.SliderFlags_.logarithmic)
        ui.edit_field("environment strength", changed, lambda s: edits.turn_environment(s, strength=strength))


def sun_on_widget(elevation_deg: float, azimuth_deg: float, radius: float) -> tuple[float, float]:
    """Where the sun shows on the hemisphere widget, from its centre in pixels (x right, y down): the sky seen from
    above with the camera's side (+z) down and +x right; the zenith at the centre, the horizon on the rim."""
    r = radius * (90.0 - elevation_deg) / 90.0
    a = math.radians(azimuth_deg)
    return r * math.sin(a), r * math.cos(a)


def sun_from_widget(dx: float, dy: float, radius: float) -> tuple[float, float]:
    """The sun's elevation and azimuth (degrees) at widget offset (dx, dy) pixels from its centre (the rim and past
    it: the horizon)."""
    r = min(math.hypot(dx, dy) / max(radius, 1e-9), 1.0)
    return 90.0 * (1.0 - r), math.degrees(math.atan2(dx, dy))


def _sun_hemisphere(ui: Interface, sky: SkySpec) -> None:
    """The sun on its hemisphere, seen from above: drag it (a preview on the way, one undo step on release)."""
    side = SUN_WIDGET_SIDE
    corner = imgui.get_cursor_screen_pos()
    imgui.invisible_button("sun hemisphere", imgui.ImVec2(side, side))
    centre = imgui.ImVec2(corner.x + side / 2, corner.y + side / 2)
    radius = side / 2 - 8
    draw = imgui.get_window_draw_list()
    line = imgui.get_color_u32(imgui.ImVec4(0.6, 0.6, 0.65, 1.0))
    draw.add_circle_filled(centre, radius, imgui.get_color_u32(imgui.ImVec4(0.18, 0.24, 0.34, 1.0)), 48)
    for ring in (1.0, 2.0 / 3.0, 1.0 / 3.0):  # the horizon, 30 and 60 degrees up
        draw.add_circle(centre, radius * ring, line, 48)
    draw.add_line(imgui.ImVec2(centre.x - radius, centre.y), imgui.ImVec2(centre.x + radius, centre.y), line)
    draw.add_line(imgui.ImVec2(centre.x, centre.y - radius), imgui.ImVec2(centre.x, centre.y + radius), line)
    draw.add_text(imgui.ImVec2(centre.x - 20, centre.y + radius - 2), line, "camera")
    x, y = sun_on_widget(sky.sun_elevation_deg, sky.sun_azimuth_deg, radius)
    draw.add_circle_filled(imgui.ImVec2(centre.x + x, centre.y + y), 6.0,
                           imgui.get_color_u32(imgui.ImVec4(1.0, 0.75, 0.2, 1.0)))
    if imgui.is_item_active():
        mouse = imgui.get_mouse_pos()
        elevation, azimuth = sun_from_widget(mouse.x - centre.x, mouse.y - centre.y, radius)
        if (elevation, azimuth) != (sky.sun_elevation_deg, sky.sun_azimuth_deg):
            ui.app.edit(lambda s: edits.set_sky(s, elevation, azimuth, sky.turbidity), preview=True)
    if imgui.is_item_deactivated():
        ui.app.commit_preview()
    if imgui.is_item_hovered():
        imgui.set_tooltip("The sky from above, the camera's side down: drag the sun (centre: overhead; rim: horizon)")


class EnvironmentPreview:
    """The Light tab's picture of the environment (renderer.environment.environment_thumbnail), its texture made
    again only when the scene's environment changes."""

    def __init__(self) -> None:
        self.texture: moderngl.Texture | None = None
        self._shown: tuple | None = None

    def draw(self, ui: Interface) -> None:
        scene = ui.app.scene
        key = (scene.environment, scene.base_dir)
        if scene.environment is None:
            return
        if self.texture is None or self._shown != key:
            try:
                light = environment_light(scene)
            except InputError:
                return  # the environment's own edit says why
            self.texture = upload_image(ui.app.window.ctx, self.texture, environment_thumbnail(light))
            self._shown = key
        w, h = self.texture.size
        imgui.image(imgui.ImTextureRef(self.texture.glo), imgui.ImVec2(w, h))
        if imgui.is_item_hovered():
            imgui.set_tooltip("The environment all around the scene, as it lights it (turned, scaled; the sun a dot):\n"
                              "the middle looks from behind the camera, the top is overhead.")

    def close(self) -> None:
        if self.texture is not None:
            self.texture.release()
            self.texture = None


def load_environment(ui: Interface) -> None:
    if ui.app.edit(lambda s: edits.use_environment_image(s, ui.fields.environment_path)):
        ui.fields.show_environment_field = False
        ui.app.say(f"lit by {ui.app.scene.environment_path()}")


def draw_floor(ui: Interface) -> None:
    """The floor: its color, or a texture image repeated over it and how far one repeat spans; square or disk."""
    app, floor = ui.app, ui.app.scene.floor
    if floor.texture is None:
        changed, c = imgui.color_edit3("floor color", list(floor.color))
        ui.edit_field("floor color", changed, lambda s: edits.set_floor_color(s, tuple(c)))
    else:
        changed, scale = imgui.slider_float("texture repeat", floor.texture_scale, edits.MIN_TEXTURE_SCALE, 10.0,
                                            "%.2f units", imgui.SliderFlags_.logarithmic)
        ui.edit_field("floor texture scale", changed, lambda s: edits.set_floor_texture_scale(s, scale))
        imgui.same_line()
        if imgui.button("No texture"):
            app.edit(edits.clear_floor_texture)
    shapes = list(FLOOR_SHAPES)
    changed, chosen = imgui.combo("floor shape", shapes.index(floor.shape), shapes)
    if changed and shapes[chosen] != floor.shape:
        app.edit(lambda s: edits.set_floor_shape(s, shapes[chosen]))
    imgui.set_next_item_width(200)
    _, ui.fields.floor_texture_path = imgui.input_text("##floor texture", ui.fields.floor_texture_path)
    ui.browse_button("floor texture", TEXTURE_FILES, "floor_texture_path")
    imgui.same_line()
    if imgui.button("Load floor texture") and ui.fields.floor_texture_path:
        if app.edit(lambda s: edits.use_floor_texture(s, ui.fields.floor_texture_path)):
            app.say(f"floor textured by {app.scene.floor_texture_path()}")


def _area_light_position(ui: Interface) -> None:
    scene = ui.app.scene
    changed, p = imgui.drag_float3("light x, y, z", list(scene.light.position), 0.01, -edits.MAX_POSITION,
                                   edits.MAX_POSITION, "%.2f")
    ui.edit_field("light", changed, lambda s: edits.move_light(s, tuple(p)))


def draw_material(ui: Interface) -> None:
    """The object's material: a preset, then roughness, specular and metallic."""
    material = ui.app.selected_object.material
    names = list(edits.MATERIAL_PRESETS)
    current = next((i for i, n in enumerate(names) if edits.MATERIAL_PRESETS[n] == material), -1)
    imgui.set_next_item_width(150)
    changed, chosen = imgui.combo("material", current, names) if current >= 0 else imgui.combo(
        "material", 0, ["custom", *names])
    if changed:
        name = names[chosen] if current >= 0 else (None if chosen == 0 else names[chosen - 1])
        if name is not None:
            ui.app.edit_object(lambda s: edits.set_material(s, edits.MATERIAL_PRESETS[name]))
    for key, label in (("roughness", "roughness"), ("specular", "specular"), ("metallic", "metallic")):
        changed, value = imgui.slider_float(label, getattr(material, key), 0.0, 1.0, "%.2f")
        ui.edit_field(f"material {key}", changed, lambda s, k=key, v=value: edits.set_material(s, _with(material, k, v)),
                      of_object=True)


def _with(material: MaterialSpec, key: str, value: float) -> MaterialSpec:
    from dataclasses import replace

    return replace(material, **{key: value})
