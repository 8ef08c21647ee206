"""Material looks for the `default` setting, the stand-in for ShapeNet's own per-part materials.

Each part of a category has a role (frame, surface, soft, upholstery, cushions); each role
gets one material (wood, metal, plastic, fabric, leather) with its own colour and fine
variation, so legs share one wood and a seat may be upholstered. A look colours surface
points given the part's main axis, along which wood grain and brushed metal run.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from renderer.objects.noise import fractal, make_lattice, value_noise
from renderer.objects.palette import hsv_color

Look = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (points (n, 3), part axis (3,)) -> sRGB (n, 3)


def _grain_frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors across `axis`, completing it to an orthonormal frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(axis, u)


def wood(rng: np.random.Generator) -> Look:
    """Warm brown with growth rings running along the part, wobbled by noise stretched along the grain."""
    base = hsv_color(rng, (0.05, 0.11), (0.35, 0.7), (0.3, 0.85))
    lattice = make_lattice(rng, 3)
    period = rng.uniform(0.015, 0.04)
    heart = rng.uniform(-0.6, 0.6, size=2)  # the tree's centre line, off the part so rings show as streaks

    def look(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
        u, v = _grain_frame(axis)
        a, b, along = points @ u, points @ v, points @ axis
        wobble = fractal(value_noise, lattice, np.column_stack([a / 0.05, b / 0.05, along / 0.4]), 3)
        radius = np.hypot(a - heart[0], b - heart[1]) + 0.04 * wobble
        ring = (radius / period) % 1.0
        shade = 0.8 + 0.25 * ring**2 + 0.1 * (wobble - 0.5)
        return np.clip(base * shade[:, None], 0.0, 1.0)

    return look


def metal(rng: np.random.Generator) -> Look:
    """Grey to near-black with faint brushing along the part."""
    base = hsv_color(rng, (0.0, 1.0), (0.0, 0.08), (0.12, 0.85))
    lattice = make_lattice(rng, 3)

    def look(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
        u, v = _grain_frame(axis)
        brushed = value_noise(lattice, np.column_stack([points @ u / 0.01, points @ v / 0.01, points @ axis / 0.3]))
        return np.clip(base * (0.95 + 0.1 * brushed)[:, None], 0.0, 1.0)

    return look


def plastic(rng: np.random.Generator) -> Look:
    """One flat colour, bright or plain."""
    base = hsv_color(rng, (0.0, 1.0), (0.0, 0.9), (0.15, 0.95))
    return lambda points, axis: np.tile(base, (len(points), 1))


def fabric(rng: np.random.Generator) -> Look:
    """Muted colour with a fine weave-like speckle and soft blotches."""
    base = hsv_color(rng, (0.0, 1.0), (0.1, 0.7), (0.2, 0.85))
    lattice = make_lattice(rng, 3)

    def look(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
        fine = value_noise(lattice, points / 0.012)
        blotch = fractal(value_noise, lattice, points / 0.1, 2)
        return np.clip(base * (0.88 + 0.1 * fine + 0.08 * blotch)[:, None], 0.0, 1.0)

    return look


def leather(rng: np.random.Generator) -> Look:
    """Black, brown, tan or oxblood with a slightly mottled surface."""
    base = hsv_color(rng, (-0.03, 0.1), (0.3, 0.85), (0.08, 0.65))
    lattice = make_lattice(rng, 3)

    def look(points: np.ndarray, axis: np.ndarray) -> np.ndarray:
        mottle = fractal(value_noise, lattice, points / 0.03, 3)
        return np.clip(base * (0.88 + 0.2 * mottle)[:, None], 0.0, 1.0)

    return look


MATERIALS: dict[str, Callable[[np.random.Generator], Look]] = {
    "wood": wood,
    "metal": metal,
    "plastic": plastic,
    "fabric": fabric,
    "leather": leather,
}

# Role -> (material weights, (earlier role whose material it shares, with what probability) or None).
ROLES: dict[str, tuple[dict[str, float], tuple[str, float] | None]] = {
    "frame": ({"wood": 5, "metal": 4, "plastic": 1}, None),
    "surface": ({"wood": 4, "plastic": 2, "fabric": 2, "leather": 1}, ("frame", 0.4)),
    "soft": ({"fabric": 7, "leather": 3}, None),
    "upholstery": ({"fabric": 3, "leather": 1}, None),
    "cushions": ({"fabric": 7, "leather": 3}, ("upholstery", 0.7)),
}


def choose_materials(rng: np.random.Generator) -> dict[str, tuple[str, Look]]:
    """A material (name and look) for every role, roles drawn in order so shared materials are the same instance."""
    chosen: dict[str, tuple[str, Look]] = {}
    for role, (weights, shared) in ROLES.items():
        if shared is not None and rng.random() < shared[1]:
            chosen[role] = chosen[shared[0]]
            continue
        names = list(weights)
        p = np.array([weights[n] for n in names], dtype=float)
        name = names[int(rng.choice(len(names), p=p / p.sum()))]
        chosen[role] = (name, MATERIALS[name](rng))
    return chosen
