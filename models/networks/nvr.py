"""NVR and NVR+ (paper sections 3.3 and 3.4), built from an `NVRConfig`, with cacheable stages.

Input/output convention (the one place it is written down):
- voxels: (B, 4, D, H, W) float32, D = H = W = config.grid_size; channels R, G, B (sRGB in
  [0, 1]) and occupancy (0 or 1); indexed [depth, row, column] as renderer/camera.py defines
  the camera-aligned grid (depth 0 nearest the camera, row 0 at the top, column 0 at the left).
- light: (B, config.light_dims) float32: the light's position in camera coordinates
  (renderer.camera.Camera.world_to_camera) divided by LIGHT_SCALE = CAMERA_DISTANCE, so the
  look-at point is (0, 0, -1); `light_to_network` makes it from a world position. With
  config.environment_input it goes on with whether the area light is on (1 or 0), the object's
  roughness, specular and metallic, and the environment probe (renderer.environment.environment_probe,
  PROBE_SIZE^2, world frame) as log(1 + radiance), channels first; `lighting_input` makes all of it.
- splat (NVR+ only): (B, 3, S, S) float32 sRGB in [0, 1], S = config.output_size, the splatted
  image of the same scene and camera.
- floor_light (NVR+ with config.floor_light_input only): (B, 3, S, S) float32 sRGB in [0, 1], the
  lit empty floor of the same scene (renderer.floor_light.lit_floor_image); it depends on the light.
- shading (NVR+ with config.shading_input only): (B, SHADING_CHANNELS, S, S) float32, the voxel
  shader's image and buffers (renderer.shading.network_buffers, channels first); channels 0-2 are
  the shaded image, sRGB. It depends on the light.
- output: (B, 3, S, S) float32 sRGB, squashed into (0, 1) by a sigmoid (never clamped, so every
  pixel keeps a gradient). With shading_input: the shaded image corrected, shaded * exp(gain) +
  offset, gain and offset per pixel and channel from the network (not squashed: clamp for display);
  their layer starts at zero, so an untrained network renders the shaded image exactly, and a
  multiplicative correction keeps the texture the shaded image already has. With
  config.correction_downsampling above 1 the network's 2D layers work on its inputs area-averaged to
  config.network_size, and gain and offset are upsampled bilinearly to S before they are applied.

Stages, so a live engine can cache what an edit does not change:
`encode_voxels(voxels) -> latent` does not depend on the light, nor does
`encode_splat(splat, floor_light) -> features` unless it reads the lit floor;
`render_from_latent(latent, light, splat_features)` is everything from the light merge on (NVR+:
`correction_from_latent`, then `apply_correction` to the shaded image);
`forward(voxels, light, splat, floor_light)` composes them.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from models.networks.config import (
    IMAGE_CHANNELS,
    LIGHT_DIMS,
    LIGHTING_SCALARS,
    PROBE_SIZE,
    VOXEL_CHANNELS_IN,
    NVRConfig,
)
from models.networks.layers import (
    ResidualBlock2d,
    ResidualBlock3d,
    ResidualStack,
    cat_channels,
    conv_2d,
    conv_block_2d,
    conv_block_3d,
    up_block_2d,
)
from renderer.camera import Camera
from renderer.scene import CAMERA_DISTANCE, Scene, needs_environment_shading
from renderer.shading import BUFFER_CHANNELS

LIGHT_SCALE = CAMERA_DISTANCE
SHADING_CHANNELS = len(BUFFER_CHANNELS)


def light_to_network(light_world: np.ndarray, elevation_deg: float) -> np.ndarray:
    """World light position(s) (..., 3) to the network's light input (camera coordinates / LIGHT_SCALE)."""
    w2c = Camera(elevation_deg=elevation_deg).world_to_camera()
    p = np.asarray(light_world, dtype=np.float64)
    return ((p @ w2c[:3, :3].T + w2c[:3, 3]) / LIGHT_SCALE).astype(np.float32)


def lighting_input(scene: Scene, environment_input: bool) -> np.ndarray:
    """The network's light input (config.light_dims,) for a scene: the light's position (light_to_network), and for a
    network with config.environment_input the area light's switch, the material and the environment probe (the
    uniform ambient light where the scene has no environment)."""
    light = light_to_network(scene.light.position, scene.camera.elevation_deg)
    if not environment_input:
        return light
    from renderer.environment import environment_probe
    from renderer.shading.environment_shading import scene_environment

    m = scene.object.material
    scalars = np.array([float(scene.light.enabled), m.roughness, m.specular, m.metallic], dtype=np.float32)
    probe = np.log1p(environment_probe(scene_environment(scene), PROBE_SIZE)).transpose(2, 0, 1)
    return np.concatenate([light, scalars, probe.ravel()]).astype(np.float32)


# --- branches -------------------------------------------------------------------------------


class VoxelEncoder(nn.Module):
    """Voxels -> 2D latent: strided 3D convs, 3D residual blocks, projection unit, 2D residual blocks."""

    def __init__(self, config: NVRConfig):
        super().__init__()
        stages, c_in = [], VOXEL_CHANNELS_IN
        for c_out, stride, kernel in zip(config.voxel_channels, config.voxel_strides, config.voxel_kernels):
            stages.append(conv_block_3d(c_in, c_out, kernel, stride))
            c_in = c_out
        self.stages = nn.Sequential(*stages)
        self.residual = ResidualStack(lambda: ResidualBlock3d(c_in), config.voxel_res_blocks)
        # Projection unit: depth folded into channels, then a 1x1 convolution.
        self.projection = conv_block_2d(c_in * config.latent_size, config.latent_channels, 1)
        self.blocks = ResidualStack(lambda: ResidualBlock2d(config.latent_channels), config.pre_light_blocks)

    def forward(self, voxels: torch.Tensor) -> torch.Tensor:
        x = self.residual(self.stages(voxels))
        b, c, d, h, w = x.shape
        return self.blocks(self.projection(x.reshape(b, c * d, h, w)))


class EnvironmentEncoder(nn.Module):
    """The environment probe, the area light's switch and the material -> a code added to the light's: strided
    convolutions over the probe (32 -> 4 texels a side), then two FC layers that also read the scalars. The last
    layer starts at zero, so a network given this encoder renders what it rendered without it."""

    def __init__(self, config: NVRConfig):
        super().__init__()
        n, widths = config.light_channels, (16, 32, 32)
        layers, c_in = [], IMAGE_CHANNELS
        for c_out in widths:
            layers += [nn.Conv2d(c_in, c_out, 4, stride=2, padding=1), nn.ReLU()]
            c_in = c_out
        self.probe = nn.Sequential(*layers)
        probe_features = c_in * (PROBE_SIZE // 2 ** len(widths)) ** 2
        self.mlp = nn.Sequential(nn.Linear(probe_features + LIGHTING_SCALARS, n), nn.ReLU(), nn.Linear(n, n))
        nn.init.zeros_(self.mlp[-1].weight)
        nn.init.zeros_(self.mlp[-1].bias)

    def forward(self, scalars: torch.Tensor, probe: torch.Tensor) -> torch.Tensor:
        features = self.probe(probe.reshape(-1, IMAGE_CHANNELS, PROBE_SIZE, PROBE_SIZE)).flatten(1)
        return self.mlp(torch.cat([features, scalars], dim=1))


def light_code(light_mlp: nn.Module, environment: EnvironmentEncoder | None, light: torch.Tensor) -> torch.Tensor:
    """The light code (B, light_channels) from the light input: the position's FCs, and with an environment encoder
    those FCs gated by the area light's switch plus the environment's code."""
    code = light_mlp(light[:, :LIGHT_DIMS])
    if environment is None:
        return code
    scalars = light[:, LIGHT_DIMS:LIGHT_DIMS + LIGHTING_SCALARS]
    return code * scalars[:, :1] + environment(scalars, light[:, LIGHT_DIMS + LIGHTING_SCALARS:])


class LightDecoder(nn.Module):
    """Latent + light -> full-resolution features: light FCs tiled, merge, residual blocks, upsampling."""

    def __init__(self, config: NVRConfig):
        super().__init__()
        n = config.light_channels
        self.light_mlp = nn.Sequential(nn.Linear(LIGHT_DIMS, n), nn.ReLU(), nn.Linear(n, n))
        self.environment = EnvironmentEncoder(config) if config.environment_input else None
        self.merge = conv_block_2d(config.latent_channels + n, config.latent_channels, config.merge_kernel)
        self.blocks = ResidualStack(lambda: ResidualBlock2d(config.latent_channels), config.post_light_blocks)
        layers, c_in = [], config.latent_channels
        for c_out in config.decoder_channels:
            layers += [up_block_2d(c_in, c_out), conv_block_2d(c_out, c_out, config.decoder_kernel)]
            c_in = c_out
        self.decoder = nn.Sequential(*layers)

    def forward(self, latent: torch.Tensor, light: torch.Tensor) -> torch.Tensor:
        code = light_code(self.light_mlp, self.environment, light)[:, :, None, None]
        code = code.expand(-1, -1, latent.shape[2], latent.shape[3])
        x = self.merge(torch.cat([latent, code], dim=1))
        return self.decoder(self.blocks(x))


def splat_branch_channels(config: NVRConfig) -> int:
    """Input channels of NVR+'s splat branch: the splat, and the lit floor and the shader's buffers if read."""
    return IMAGE_CHANNELS * (2 if config.floor_light_input else 1) + (SHADING_CHANNELS if config.shading_input else 0)


class SplatEncoder(nn.Module):
    """Splatting processing network: full-resolution conv blocks (no downsampling)."""

    def __init__(self, config: NVRConfig):
        super().__init__()
        layers, c_in = [], splat_branch_channels(config)
        for _ in range(config.splat_layers):
            layers.append(conv_block_2d(c_in, config.splat_channels, config.splat_kernel))
            c_in = config.splat_channels
        self.layers = nn.Sequential(*layers)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return self.layers(image)


class RerenderUNet(nn.Module):
    """Neural rerendering network: a U-Net of strided residual blocks with residual blocks in its middle.

    Level i halves the size and has `unet_channels[i]` channels; going up, each level upsamples
    to half its width, concatenates the skip of the level above and convolves to the skip's width.
    """

    def __init__(self, config: NVRConfig):
        super().__init__()
        widths = config.unet_channels
        skips = (config.splat_channels, *widths[:-1])
        self.down = nn.ModuleList(ResidualBlock2d(s, w, stride=2) for s, w in zip(skips, widths))
        self.middle = ResidualStack(lambda: ResidualBlock2d(widths[-1]), config.unet_mid_blocks)
        self.up = nn.ModuleList(up_block_2d(w, w // 2) for w in widths)
        self.fuse = nn.ModuleList(conv_block_2d(w // 2 + s, s, config.unet_kernel) for s, w in zip(skips, widths))
        self.out = conv_block_2d(config.splat_channels, config.splat_channels, config.unet_kernel)
        # A correction of the shaded image (gain and offset per channel) starts at zero: no correction.
        outputs = 2 * IMAGE_CHANNELS if config.shading_input else IMAGE_CHANNELS
        self.to_rgb = conv_2d(config.splat_channels, outputs, config.unet_kernel)
        if config.shading_input:
            for parameter in self.to_rgb.parameters():
                nn.init.zeros_(parameter)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = []
        for down in self.down:
            skips.append(x)
            x = down(x)
        x = self.middle(x)
        for level in reversed(range(len(self.down))):
            x = self.fuse[level](torch.cat([self.up[level](x), skips[level]], dim=1))
        return self.to_rgb(self.out(x))


# --- the two networks -----------------------------------------------------------------------


class _VoxelRenderer(nn.Module):
    """What NVR and NVR+ share: the voxel branch, the light decoder, and input checks."""

    def __init__(self, config: NVRConfig):
        super().__init__()
        self.config = config
        self.voxel_encoder = VoxelEncoder(config)
        self.light_decoder = LightDecoder(config)

    def encode_voxels(self, voxels: torch.Tensor) -> torch.Tensor:
        """Light-independent latent (B, latent_channels, s, s) of the voxel grid."""
        g = self.config.grid_size
        _check_shape("voxels", voxels, (VOXEL_CHANNELS_IN, g, g, g))
        return self.voxel_encoder(voxels)

    def _features(self, latent: torch.Tensor, light: torch.Tensor) -> torch.Tensor:
        _check_shape("light", light, (self.config.light_dims,))
        if light.shape[0] != latent.shape[0]:
            raise ValueError(f"light has batch {light.shape[0]}, latent has batch {latent.shape[0]}")
        return self.light_decoder(latent, light)


class NVR(_VoxelRenderer):
    """Neural Voxel Renderer: voxels and light -> image."""

    architecture = "nvr"

    def __init__(self, config: NVRConfig):
        super().__init__(config)
        c = config.decoder_channels[-1]
        self.to_rgb = conv_2d(c, IMAGE_CHANNELS, config.decoder_kernel)

    def render_from_latent(self, latent: torch.Tensor, light: torch.Tensor, splat_features: torch.Tensor | None = None,
                           shaded: torch.Tensor | None = None) -> torch.Tensor:
        """Image (B, 3, S, S) from a cached latent and the light; NVR takes no splat and no shaded image."""
        if splat_features is not None or shaded is not None:
            raise ValueError("NVR takes no splat or shaded image; use NVRPlus")
        return torch.sigmoid(self.to_rgb(self._features(latent, light)))

    def forward(self, voxels: torch.Tensor, light: torch.Tensor, splat: torch.Tensor | None = None,
                floor_light: torch.Tensor | None = None) -> torch.Tensor:
        if splat is not None or floor_light is not None:
            raise ValueError("NVR takes no splat or lit floor; use NVRPlus")
        return self.render_from_latent(self.encode_voxels(voxels), light)


class NVRPlus(_VoxelRenderer):
    """NVR+: NVR's full-resolution features plus the processed splat, rerendered by a U-Net."""

    architecture = "nvr_plus"

    def __init__(self, config: NVRConfig):
        super().__init__(config)
        self.to_features = conv_2d(config.decoder_channels[-1], config.splat_channels, config.decoder_kernel)
        self.splat_encoder = SplatEncoder(config)
        self.rerender = RerenderUNet(config)

    def encode_splat(self, splat: torch.Tensor, floor_light: torch.Tensor | None = None,
                     shading: torch.Tensor | None = None) -> torch.Tensor:
        """Features (B, splat_channels, N, N), N = config.network_size, of the splatted image, and of the lit floor
        and the shader's buffers if the config reads them."""
        s = self.config.output_size
        _check_shape("splat", splat, (IMAGE_CHANNELS, s, s))
        inputs = [splat]
        for name, label, tensor, wanted, channels in (
                ("floor_light", "lit floor", floor_light, self.config.floor_light_input, IMAGE_CHANNELS),
                ("shading", "shader buffers", shading, self.config.shading_input, SHADING_CHANNELS)):
            if not wanted:
                if tensor is not None:
                    raise ValueError(f"this network reads no {label} (config.{name}_input is false)")
                continue
            if tensor is None:
                raise ValueError(f"this network reads the {label} too (config.{name}_input): pass {name}")
            _check_shape(name, tensor, (channels, s, s))
            inputs.append(tensor)
        joined = cat_channels(inputs)
        factor = self.config.correction_downsampling
        if factor > 1:
            # One pool over the joined channels: on channels-last inputs a pool per input is several times slower.
            joined = F.avg_pool2d(joined, factor)
        return self.encode_joined(joined)

    def encode_joined(self, joined: torch.Tensor) -> torch.Tensor:
        """encode_splat after its inputs are joined along the channels (splat, lit floor, shader buffers, as read)
        and area-averaged to (B, C, N, N), N = config.network_size: for a caller that joins them itself."""
        return self.splat_encoder(joined)

    def correction_from_latent(self, latent: torch.Tensor, light: torch.Tensor,
                               splat_features: torch.Tensor | None) -> torch.Tensor:
        """What the U-Net draws from a cached latent, the light and cached splat features, before it is applied:
        (B, 3, S, S) logits of the image, or with shading_input gain and offset (B, 6, N, N), N = config.network_size
        (apply_correction)."""
        if splat_features is None:
            raise ValueError("NVRPlus needs splat features (encode_splat)")
        return self.rerender(self.to_features(self._features(latent, light)) + splat_features)

    def apply_correction(self, correction: torch.Tensor, shaded: torch.Tensor | None) -> torch.Tensor:
        """The image (B, 3, S, S) from correction_from_latent's output and, with shading_input, the shaded image
        (B, 3, S, S) it corrects: shaded * exp(gain) + offset, gain and offset upsampled bilinearly to S."""
        if not self.config.shading_input:
            return torch.sigmoid(correction)
        if shaded is None:
            raise ValueError("this network corrects the shaded image (config.shading_input): pass shaded")
        if self.config.correction_downsampling > 1:
            correction = F.interpolate(correction, scale_factor=self.config.correction_downsampling, mode="bilinear",
                                       align_corners=False)
        gain, offset = correction[:, :IMAGE_CHANNELS], correction[:, IMAGE_CHANNELS:]
        # exp of a dense copy (clone keeps the layout): on a strided channel slice it is not vectorised, 10x slower
        return torch.addcmul(offset, shaded, gain.clone().exp())

    def render_from_latent(self, latent: torch.Tensor, light: torch.Tensor,
                           splat_features: torch.Tensor | None = None, shaded: torch.Tensor | None = None) -> torch.Tensor:
        """Image (B, 3, S, S) from a cached latent, the light and cached splat features; with shading_input
        also the shaded image (B, 3, S, S) the output corrects."""
        return self.apply_correction(self.correction_from_latent(latent, light, splat_features), shaded)

    def forward(self, voxels: torch.Tensor, light: torch.Tensor, splat: torch.Tensor | None = None,
                floor_light: torch.Tensor | None = None, shading: torch.Tensor | None = None) -> torch.Tensor:
        if splat is None:
            raise ValueError("NVRPlus needs a splat image")
        features = self.encode_splat(splat, floor_light, shading)
        shaded = shading[:, :IMAGE_CHANNELS] if shading is not None else None
        return self.render_from_latent(self.encode_voxels(voxels), light, features, shaded)


ARCHITECTURES: dict[str, type[_VoxelRenderer]] = {NVR.architecture: NVR, NVRPlus.architecture: NVRPlus}
SHARED_BRANCHES = ("voxel_encoder.", "light_decoder.")  # state-dict prefixes of _VoxelRenderer's layers: both have them
ENVIRONMENT_ENCODER = "light_decoder.environment."  # state-dict prefix of the EnvironmentEncoder (environment_input)


def reads_floor_light(architecture: str, config: NVRConfig | None) -> bool:
    """Whether a network of this architecture and config takes the lit empty floor as an input."""
    return architecture == NVRPlus.architecture and config is not None and config.floor_light_input


def reads_shading(architecture: str, config: NVRConfig | None) -> bool:
    """Whether a network of this architecture and config reads the voxel shader's buffers (and corrects its image)."""
    return architecture == NVRPlus.architecture and config is not None and config.shading_input


def reads_scene(config: NVRConfig, scene: Scene) -> bool:
    """Whether a network of this config renders the scene: one lit by an environment, with the area light off, a
    glossy object or a textured or round floor only if it reads the environment (config.environment_input), and then
    of one object (its light input holds one material). For the rest it shows the voxel shader's image."""
    if config.environment_input:
        return len(scene.objects) == 1
    return not needs_environment_shading(scene)


def build_model(architecture: str, config: NVRConfig) -> NVR | NVRPlus:
    """A fresh network of the named architecture ('nvr' or 'nvr_plus')."""
    if architecture not in ARCHITECTURES:
        raise ValueError(f"unknown architecture {architecture!r} (choose from {', '.join(ARCHITECTURES)})")
    return ARCHITECTURES[architecture](config)


def _check_shape(name: str, tensor: torch.Tensor, per_item: tuple[int, ...]) -> None:
    if tensor.ndim != len(per_item) + 1 or tuple(tensor.shape[1:]) != per_item:
        raise ValueError(f"{name} must have shape (B, {', '.join(map(str, per_item))}), got {tuple(tensor.shape)}")
