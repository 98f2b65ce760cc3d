"""The seed's arena (Section 1): a 1.5 m x 1.5 m square with eight AprilTags on its walls.

The world origin is the centre of the square, x to the right and y up in the seed's Figure 1, so
the walls are the lines x = ±0.75 m and y = ±0.75 m. Two tags sit on each wall, at a quarter of
the side from each corner, and every tag faces into the arena. Tag ids 0..7 follow the order in
which the seed lists the coordinates. The robot's nominal start is (-0.375, -0.375, 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam import checks
from ekfslam.errors import ConfigError
from ekfslam.fieldtypes import field_types, finite

Array = NDArray[np.float64]


def _frozen_array(values: ArrayLike, shape: tuple[int, ...], name: str) -> Array:
    a = checks.array(values, name, shape, f"{shape[0]} finite numbers").copy()
    a.flags.writeable = False  # the dataclasses are frozen; their arrays should be too
    return a


@dataclass(frozen=True, eq=False)
class Tag:
    """One landmark: id, centre position (2,) in m and unit outward normal (2,) of its face.

    The tag can be read only from the half-plane its normal points into.
    """

    id: int
    position: Array
    normal: Array

    def __post_init__(self) -> None:
        field_types(self)
        object.__setattr__(self, "position", _frozen_array(self.position, (2,), "Tag.position"))
        normal = _frozen_array(self.normal, (2,), "Tag.normal")
        if not np.isclose(np.hypot(*normal), 1.0):
            raise ConfigError(f"Tag.normal must be a unit vector, got {normal.tolist()}")
        object.__setattr__(self, "normal", normal)


@dataclass(frozen=True, eq=False)
class Arena:
    """A square arena centred at the origin.

    half_size : distance (m) from the centre to each wall.
    tags : the landmarks, in id order.
    nominal_start : (3,) the pose (x, y, θ) where the robot is meant to be placed.
    """

    half_size: float
    tags: tuple[Tag, ...]
    nominal_start: Array = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        field_types(self)
        if not finite(self.half_size) or self.half_size <= 0:
            raise ConfigError(f"Arena.half_size must be a positive length, got {self.half_size!r}")
        ids = [tag.id for tag in self.tags]
        if len(set(ids)) != len(ids):
            raise ConfigError(f"Arena tag ids must be unique, got {ids}")
        start = _frozen_array(self.nominal_start, (3,), "Arena.nominal_start")
        object.__setattr__(self, "nominal_start", start)
        object.__setattr__(self, "tags", tuple(self.tags))

    @property
    def tag_ids(self) -> NDArray[np.int64]:
        """(n,) the tag ids, in the arena's order."""
        return np.array([tag.id for tag in self.tags], dtype=np.int64)

    def tag_map(self) -> dict[int, Array]:
        """{tag id: (2,) position in m}, the form `ekfslam.logs.runlog.RunMeta.tag_map` takes."""
        return {tag.id: tag.position.copy() for tag in self.tags}

    def tag_positions(self) -> Array:
        """(n, 2) tag positions in m, in the arena's order."""
        return np.array([tag.position for tag in self.tags]).reshape(-1, 2)

    def tag_normals(self) -> Array:
        """(n, 2) unit normals of the tag faces, in the arena's order."""
        return np.array([tag.normal for tag in self.tags]).reshape(-1, 2)

    def contains(self, point: ArrayLike, margin: float = 0.0) -> bool | NDArray[np.bool_]:
        """Whether point(s) lie inside the arena, at least `margin` m away from every wall.

        Parameters
        ----------
        point : array (2,) or (N, 2), or poses (3,) / (N, 3) whose heading is ignored.
        margin : float, m.

        Returns
        -------
        bool for one point, bool array (N,) for many.
        """
        p = np.asarray(point, dtype=float)
        inside = np.all(np.abs(p[..., :2]) <= self.half_size - margin, axis=-1)
        return bool(inside) if inside.ndim == 0 else inside


def _wall_tag(tag_id: int, x: float, y: float, half_size: float) -> Tag:
    """A tag on the wall it touches, facing the centre (a tag on x = +0.75 faces -x)."""
    if np.isclose(abs(x), half_size):
        normal = (-np.sign(x), 0.0)
    elif np.isclose(abs(y), half_size):
        normal = (0.0, -np.sign(y))
    else:
        raise ValueError(f"tag {tag_id} at ({x}, {y}) is not on a wall of the arena")
    return Tag(tag_id, np.array([x, y]), np.array(normal))


#: The tag centres of the seed's Section 1, in the seed's order (ids 0..7), in m.
SEED_TAG_POSITIONS: tuple[tuple[float, float], ...] = (
    (0.75, 0.375),
    (0.75, -0.375),
    (0.375, -0.75),
    (0.375, 0.75),
    (-0.375, 0.75),
    (-0.75, 0.375),
    (-0.75, -0.375),
    (-0.375, -0.75),
)


def seed_arena() -> Arena:
    """The seed's arena: half size 0.75 m, eight wall tags, nominal start (-0.375, -0.375, 0)."""
    half_size = 0.75
    tags = tuple(_wall_tag(i, x, y, half_size) for i, (x, y) in enumerate(SEED_TAG_POSITIONS))
    return Arena(half_size, tags, np.array([-0.375, -0.375, 0.0]))


#: The seed's arena, `seed_arena()`: 1.5 m square, 8 tags on the walls, start (-0.375, -0.375, 0).
SEED_ARENA = seed_arena()
