"""How far the handle is from its virtual mechanism: the log's columns dist, dist_signed,
dist_normal, dist_across [m], by each mechanism kind's measure in the core (one definition,
next to the kind: src/kinds/*.cpp; `virtmech.distances` computes a block of rows at once).

- ``dist_signed``: the signed distance of the mechanism's point (the handle for a PlanarArm
  or a HandlePath, the stylus tip for the probes: the handle moved by the mechanism's
  ``length`` along the stylus) from the mechanism's path or surface; negative on the side
  the mechanism pushes away from (behind a Probe's plane, below a PointPivot's or
  LineGuide's point or line along its normal, inside a PlanarArm's circle).
- ``dist``: the distance from where the mechanism lets that point be (>= 0): the same size
  for a bilateral mechanism; for a unilateral one, zero wherever the tip has lifted off.
- ``dist_normal``: the part along the mechanism's normal.
- ``dist_across``: the rest.

A kind without a measure (a SerialChain, a plugin's kind that gives none): the size of the
nearest placement's position error in dist and dist_signed, its two parts NaN.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass

import numpy as np

import virtmech as vm

#: the columns of a measure, in the log's order
COLUMNS = ("dist", "dist_signed", "dist_normal", "dist_across")


@dataclass(frozen=True)
class Distances:
    dist: np.ndarray
    dist_signed: np.ndarray
    dist_normal: np.ndarray
    dist_across: np.ndarray

    def columns(self) -> np.ndarray:
        return np.stack([getattr(self, c) for c in COLUMNS], axis=1)


@dataclass(frozen=True)
class Geometry:
    """How figures and reports name a kind's distance (its registry entry's)."""

    point: str  # the point measured: "handle" or "tip"
    target: str  # what it is measured from: "the circle", "the plane", ...
    signed_label: str  # the signed distance's name in figures
    negative: str  # what a negative signed distance means


def _geometries() -> dict[str, Geometry]:
    return {k["name"]: Geometry(k["point"], k["target"], k["signed_label"], k["negative"])
            for k in vm.kinds("mechanism") if k["distance"]}


class _Kinds(Mapping):
    """mechanism type -> its Geometry, read from the registry at each use (so that a
    plugin's kinds are in it)."""

    def __getitem__(self, key: str) -> Geometry:
        return _geometries()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(_geometries())

    def __len__(self) -> int:
        return len(_geometries())


#: mechanism type -> its geometry (kinds without a measure have none)
GEOMETRY: Mapping[str, Geometry] = _Kinds()


def _type(mechanism) -> str:
    return mechanism["type"] if isinstance(mechanism, dict) else mechanism.type


def geometry_of(mechanism) -> Geometry | None:
    """The naming of a mechanism's distance (a mechanism or its to_dict()), None for a kind
    without a measure."""
    return GEOMETRY.get(_type(mechanism))


def distances(mechanism, p: np.ndarray, s: np.ndarray, e_pos: np.ndarray) -> Distances:
    """The four distance columns for handle positions p and stylus directions s (N, 3) from
    a mechanism (or its to_dict()); e_pos (N, 3): the nearest placement's position errors,
    for a kind without a measure."""
    if isinstance(mechanism, dict):
        mechanism = vm.make_mechanism(mechanism)
    p, s, e_pos = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (p, s, e_pos))
    d = vm.distances(mechanism, p, s, np.broadcast_to(e_pos, p.shape))
    return Distances(*d.T)
