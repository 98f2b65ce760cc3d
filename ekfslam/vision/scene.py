"""What the camera looks at: the seed's arena as textured rectangles (walls, floor, tags, room).

`build_scene` returns every surface of the scene in painting order, for `ekfslam.vision.render`:

- the room around the arena, a 4 m x 4 m box 2.4 m high, with posters, frames, shelves, a
  window and one extra tag (id `CLUTTER_TAG_ID`, not in the map) as clutter (or, without
  clutter, a plain grey backdrop);
- the arena's four walls, light-coloured boards, shaded by one light from the side;
- the floor, grey with a faint texture;
- the tags: AprilTag 36h11 of the arena's ids (0..7 in the seed's order, `ekfslam.core.arena`), each
  printed as a `TagSpec.size` black square centred on a white sheet (about A4, portrait),
  at the tag's position on its wall, the sheet's centre `tag_height` above the floor.

Tag sheets are textures at 4, 8, ... 64 texels per module, every level of the same physical
size with the black square on texel edges, so that the renderer can pick the level with about
one texel per pixel. Paper is 0.86 and toner 0.07 of a perfect white.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ekfslam.core.arena import Arena
from ekfslam.core.camera import TAG_HEIGHT, TagSpec

Array = NDArray[np.float64]

#: An id printed on a poster in the room, outside the map: detectors see it, the map refuses it.
CLUTTER_TAG_ID = 20
PAPER, INK = 0.86, 0.07  # radiance of white paper and of black toner (1 = a perfect white)


@dataclass(frozen=True, eq=False)
class Surface:
    """A textured rectangle: top-left corner, unit axes right (u) and down (v), size in m.

    levels : textures (float32 radiance) from coarse to fine; level k covers the rectangle with
    its own texel count. shade : the light falling on it (a factor on its radiance).
    """

    origin: Array
    u: Array
    v: Array
    size: tuple[float, float]
    levels: tuple[np.ndarray, ...]
    shade: float = 1.0

    def corners(self) -> Array:
        w, h = self.size
        o, u, v = self.origin, self.u, self.v
        return np.array([o, o + w * u, o + w * u + h * v, o + h * v])


def tag_image(tag_id: int, module_px: int) -> NDArray[np.uint8]:
    """The 36h11 tag `tag_id` as 8 x 8 modules of `module_px` pixels (black border included)."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    return cv2.aruco.generateImageMarker(dictionary, int(tag_id), 8 * module_px, borderBits=1)


def _sheet_levels(tag_id: int, tags: TagSpec, sheet: tuple[float, float]) -> tuple[np.ndarray, ...]:
    """The printed sheet at 4, 8, ... 64 texels per module, every level the same physical size.

    The margins are whole texels at the coarsest level (so a multiple of a quarter module), which
    keeps the black square on texel edges at every level; the sheet is `sheet` rounded to that.
    """
    module = tags.size / 8.0
    margins = [max(4, round((side / module - 8) * 4 / 2)) for side in sheet]  # coarsest texels
    marker = tag_image(tag_id, 64).astype(np.float32) / 255.0
    levels = []
    for m in (4, 8, 16, 32, 64):
        mx, my = (margin * m // 4 for margin in margins)
        img = np.full((8 * m + 2 * my, 8 * m + 2 * mx), PAPER, dtype=np.float32)
        bits = marker[:: 64 // m, :: 64 // m]  # exact: every module is 64 // m texels wide
        img[my : my + 8 * m, mx : mx + 8 * m] = INK + (PAPER - INK) * bits
        levels.append(img)
    return tuple(levels)


def _smooth_noise(rng, shape: tuple[int, int], scale: float, amplitude: float) -> np.ndarray:
    noise = rng.standard_normal(shape).astype(np.float32)
    noise = cv2.GaussianBlur(noise, (0, 0), scale)
    return amplitude * noise / max(float(noise.std()), 1e-9)


def build_scene(
    arena: Arena,
    tags: TagSpec,
    rng: np.random.Generator,
    wall_height: float = 0.35,
    tag_height: float = TAG_HEIGHT,
    sheet_size: tuple[float, float] = (0.21, 0.297),
    clutter: bool = True,
) -> tuple[Surface, ...]:
    """Every surface in painting order: room, arena walls, floor, tag sheets.

    wall_height, tag_height (of the tags' centres), sheet_size (w, h): m. rng draws the textures.
    """
    half = arena.half_size
    surfaces: list[Surface] = []
    light = np.array([0.6, 0.35])  # where the room's light comes from, in the floor plane
    light /= np.linalg.norm(light)

    def wall(centre_xy, normal, length, z_top, height, texture, shade):
        right = np.array([-normal[1], normal[0], 0.0])
        origin = np.array([*centre_xy, z_top]) - 0.5 * length * right
        return Surface(origin, right, np.array([0.0, 0.0, -1.0]), (length, height), texture, shade)

    if clutter:
        room_half, room_height = 2.0, 2.4
        for k, normal in enumerate(((-1, 0), (0, -1), (1, 0), (0, 1))):
            tex = _room_wall_texture(rng, k, tags)
            shade = 0.8 + 0.2 * float(np.dot(normal, light))
            centre = -room_half * np.array(normal, dtype=float)
            surfaces.append(
                wall(centre, normal, 2 * room_half, room_height, room_height, (tex,), shade)
            )
        ceiling = 0.7 + _smooth_noise(rng, (64, 64), 6.0, 0.03)
        surfaces.append(
            Surface(
                np.array([-room_half, -room_half, room_height]),
                np.array([1.0, 0.0, 0.0]),
                np.array([0.0, 1.0, 0.0]),
                (2 * room_half, 2 * room_half),
                (ceiling,),
            )
        )
    else:
        surfaces.append(
            Surface(  # a plain grey backdrop instead of the room
                np.array([-50.0, 50.0, 30.0]),
                np.array([1.0, 0.0, 0.0]),
                np.array([0.0, -1.0, 0.0]),
                (100.0, 100.0),
                (np.full((2, 2), 0.5, np.float32),),
            )
        )
    for normal in ((-1.0, 0.0), (0.0, -1.0), (1.0, 0.0), (0.0, 1.0)):
        length = 2 * half
        texel = 0.004
        shape = (round(wall_height / texel), round(length / texel))
        grain = _smooth_noise(rng, shape, 1.5, 0.015)
        grain += _smooth_noise(rng, shape, 12.0, 0.03)
        tex = np.clip(0.58 + grain, 0, 1).astype(np.float32)
        shade = 0.85 + 0.15 * float(np.dot(normal, light))
        centre = -half * np.array(normal)
        surfaces.append(wall(centre, normal, length, wall_height, wall_height, (tex,), shade))
    n = round(2 * half / 0.005)
    floor = np.clip(
        0.36 + _smooth_noise(rng, (n, n), 1.0, 0.02) + _smooth_noise(rng, (n, n), 20.0, 0.03), 0, 1
    )
    surfaces.append(
        Surface(
            np.array([-half, half, 0.0]),
            np.array([1.0, 0.0, 0.0]),
            np.array([0.0, -1.0, 0.0]),
            (2 * half, 2 * half),
            (floor.astype(np.float32),),
        )
    )
    for tag in arena.tags:
        levels = _sheet_levels(tag.id, tags, sheet_size)
        module = tags.size / 8.0
        hgt, m = np.array(levels[-1].shape) * module / 64  # the sheet's size, m
        shade = 0.85 + 0.15 * float(np.dot(tag.normal, light))
        # in the wall's plane: painted after the walls, the sheet covers them
        surfaces.append(
            wall(tag.position, tag.normal, m, tag_height + hgt / 2.0, hgt, levels, shade)
        )
    return tuple(surfaces)


def _room_wall_texture(rng, k: int, tags: TagSpec) -> np.ndarray:
    """A room wall 4 m x 2.4 m at 1 cm per texel: paint, posters, shelves, a window or a door."""
    h, w = 240, 400
    tex = 0.62 + _smooth_noise(rng, (h, w), 8.0, 0.03)
    for _ in range(6):  # posters and frames: dark and light rectangles of random size
        pw, ph = rng.integers(20, 90), rng.integers(20, 70)
        x, y = rng.integers(0, w - pw), rng.integers(20, h - ph - 20)
        tex[y : y + ph, x : x + pw] = rng.uniform(0.1, 0.9)
        if rng.random() < 0.5:  # a frame around it
            cv2.rectangle(tex, (int(x), int(y)), (int(x + pw), int(y + ph)), 0.05, 2)
    for _ in range(2):  # shelves: horizontal dark bars
        y, x, length = rng.integers(60, 200), rng.integers(0, w - 120), rng.integers(60, 120)
        tex[y : y + 3, x : x + length] = 0.15
    if k == 0:  # a window: bright, with mullions
        tex[40:150, 150:280] = 0.97
        tex[40:150, 213:217] = 0.2
        tex[93:97, 150:280] = 0.2
    if k == 1:  # the unknown tag: 0.16 m on a white sheet, at 1 cm per texel (2 texels/module)
        m = max(1, round(tags.size / 8.0 / 0.01))
        marker = tag_image(CLUTTER_TAG_ID, m).astype(np.float32) / 255.0
        y, x = 150, 120
        tex[y - 2 * m : y + 10 * m, x - 2 * m : x + 10 * m] = PAPER
        tex[y : y + 8 * m, x : x + 8 * m] = INK + (PAPER - INK) * marker
    return np.clip(tex, 0, 1).astype(np.float32)
