"""A capture stage with a chrome sphere for the light calibration's tests: cameras, a light, sphere positions.

Realistic geometry: two cameras 600-900 mm from the face (at the origin), 20-35 degrees either side, 640x480
with a 1000-1200 px focal length (about 0.65 mm a pixel at the face) and some barrel distortion; a light 1-1.5 m
away, above and to one side; an 80 mm chrome ball (radius 40 mm) held at a few places up to 150 mm from the face, wholly in view.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq

from facecap.cameras import Camera, Light

SPHERE_RADIUS_MM = 40.0


class Stage(NamedTuple):
    cameras: list
    light: Light
    positions: np.ndarray  # (F, 3) sphere centres, mm


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def stage(seed: int, *, n_positions: int = 5, light_kind: str = "point", size=(640, 480)) -> Stage:
    """A random stage (seeded): cameras, a light and sphere positions (the first at the face)."""
    rng = np.random.default_rng(seed)
    cameras = []
    for k, side in enumerate((-1.0, 1.0)):
        yaw = np.radians(side * rng.uniform(20, 35))
        pitch = np.radians(rng.uniform(-10, 10))
        distance = rng.uniform(600, 900)
        eye = distance * np.array([np.sin(yaw) * np.cos(pitch), np.sin(pitch), np.cos(yaw) * np.cos(pitch)])
        target = rng.uniform(-20, 20, 3)
        k1 = rng.uniform(-0.15, 0.0)
        cameras.append(Camera.look_at(f"cam{k}", eye, target, focal_px=rng.uniform(1000, 1200) * size[0] / 640,
                                      width=size[0], height=size[1], distortion=[k1, 0.5 * k1 ** 2, 0, 0]))
    # the light: 1-1.5 m from the face, 25-55 degrees to one side and 15-40 degrees up, in front
    yaw = np.radians(rng.choice([-1, 1]) * rng.uniform(25, 55))
    pitch = np.radians(rng.uniform(15, 40))
    towards = np.array([np.sin(yaw) * np.cos(pitch), np.sin(pitch), np.cos(yaw) * np.cos(pitch)])
    if light_kind == "directional":
        light = Light("directional", direction=-towards)
    else:
        light = Light("point", position=rng.uniform(1000, 1500) * towards)
    positions = [np.zeros(3)]
    while len(positions) < n_positions:  # spread over the capture volume, the whole sphere in every view
        p = rng.uniform(-150, 150, 3) * np.array([1.0, 0.8, 0.5])
        seen = [camera.project(p) for camera in cameras]
        margin = [1.3 * SPHERE_RADIUS_MM * camera.K[0, 0] / s.depth + 12 for camera, s in zip(cameras, seen)]
        inside = all(m < s.pixels[0] < camera.width - m and m < s.pixels[1] < camera.height - m
                     for camera, s, m in zip(cameras, seen, margin))
        if inside and min(np.linalg.norm(p - q) for q in positions) > 80:
            positions.append(p)
    return Stage(cameras, light, np.array(positions))


def mirror_point(centre, radius, eye, light_position):
    """The point of a sphere where a ray from ``eye`` reflects to ``light_position`` (Alhazen's problem).

    The point lies in the plane of the centre, the eye and the light, between their directions from the
    centre; the normal there makes equal angles with the ways to the eye and to the light: a 1-D root.
    """
    C = np.asarray(centre, dtype=np.float64)
    a = np.asarray(eye, dtype=np.float64) - C
    b = np.asarray(light_position, dtype=np.float64) - C
    e1 = _unit(a)
    e2 = _unit(b - (b @ e1) * e1)
    angle_b = np.arctan2(b @ e2, b @ e1)

    def unequal(phi):
        n = np.cos(phi) * e1 + np.sin(phi) * e2
        P = radius * n
        return n @ _unit(a - P) - n @ _unit(b - P)

    phi = brentq(unequal, 1e-12, angle_b - 1e-12, xtol=1e-15)
    return C + radius * (np.cos(phi) * e1 + np.sin(phi) * e2)
