"""The arm's collision geometry: convex parts per link, derived from Universal Robots'
collision meshes by ``scripts/derive_arm_collision.py`` (one ``<model>.json.gz`` per model).

Frames: the parts of link ``body`` (0 = base, i = moved by joint i) are given in the frame of
pinocchio joint i of :class:`cellrunner.planning.kinematics.ArmKinematics`, i.e. "DH frame
i-1 turned by joint i" (the base frame for body 0). Every part is a convex polytope (its
vertices, its triangles) and the parts of a link together contain that link's mesh.

Self-collision pairs (:meth:`ArmGeometry.self_pair_checked`): for every two parts of
different links the file holds what the derivation proved over the joints' whole ranges: a
lower bound of their distance (none: they can touch), and for adjacent links the largest
distance sampled over their joint's turn. A pair is checked at clearance c unless its lower
bound exceeds c, or it belongs to adjacent links that are within c of each other at every
angle of their joint (some pair of their parts is: the links meet there, by construction;
that is the joint itself, and none of their pairs is checked).

Pure data: numpy, json and gzip only (``validate`` loads none of this).
"""

from __future__ import annotations

import functools
import gzip
import json
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np

#: Link names, body 0..6 (the names of Universal Robots' description).
LINK_NAMES = ("base", "shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")


class ArmGeometryMissing(LookupError):
    """No collision geometry was derived for a model (no published collision meshes)."""


@dataclass(frozen=True)
class ConvexPart:
    """One convex part of link ``body``: vertices (n x 3, m, in the joint frame) and the
    triangles of its hull (outward, indices into the vertices). The triangles are for
    drawing and edges, not planes: some are slivers whose normals point anywhere (take
    a hull's planes from its vertices)."""

    body: int
    index: int  # among the link's parts
    vertices_m: np.ndarray
    faces: np.ndarray
    volume_m3: float

    @property
    def link(self) -> str:
        return LINK_NAMES[self.body]


@dataclass(frozen=True)
class ArmGeometry:
    """The convex parts of one arm model and what the derivation proved about its pairs."""

    model: str
    parts: tuple[ConvexPart, ...]
    #: (part index a, part index b) with a < b -> lower bound of their distance over the
    #: joint ranges (m; -inf: none proven), for the parts of different links
    pair_lower_bound_m: dict[tuple[int, int], float]
    #: part pairs of adjacent links -> their largest distance over the joint's turn (m)
    joint_max_m: dict[tuple[int, int], float]
    source: dict[str, Any]
    over_approximation_mm: dict[str, Any]

    @functools.cached_property
    def link_joint_max_m(self) -> dict[tuple[int, int], float]:
        """Adjacent links (a, a + 1) -> the largest, over their joint's turn, of their
        distance (m): at most the smallest of their part pairs' largest distances."""
        out: dict[tuple[int, int], float] = {}
        for (a, b), largest in self.joint_max_m.items():
            bodies = (self.parts[a].body, self.parts[b].body)
            out[bodies] = min(out.get(bodies, np.inf), largest)
        return out

    def self_pair_checked(self, a: int, b: int, clearance_m: float) -> bool:
        """Whether parts ``a`` and ``b`` (indices into :attr:`parts`) must be checked against
        each other when every pair keeps ``clearance_m``."""
        key = (min(a, b), max(a, b))
        if self.parts[a].body == self.parts[b].body:
            return False
        bodies = (self.parts[key[0]].body, self.parts[key[1]].body)
        if self.link_joint_max_m.get(bodies, np.inf) <= clearance_m:
            return False  # the joint between adjacent links
        return self.pair_lower_bound_m.get(key, -np.inf) <= clearance_m


def available_models() -> list[str]:
    """The models with derived geometry, sorted."""
    folder = resources.files(__name__)
    return sorted(
        p.name.removesuffix(".json.gz") for p in folder.iterdir() if p.name.endswith(".json.gz")
    )


@functools.cache
def arm_geometry(model: str) -> ArmGeometry:
    """The derived geometry of ``model``; :class:`ArmGeometryMissing` names the models
    that have some when it has none."""
    path = resources.files(__name__) / f"{model}.json.gz"
    if not path.is_file():
        raise ArmGeometryMissing(
            f"no collision geometry for robot model {model!r}: Universal Robots publishes no "
            f"collision meshes for it, and cellrunner does not guess an arm's shape "
            f"(models with geometry: {', '.join(available_models())})"
        )
    return parse_arm_geometry(json.loads(gzip.decompress(path.read_bytes())))


def parse_arm_geometry(doc: dict[str, Any]) -> ArmGeometry:
    """An :class:`ArmGeometry` from the JSON document the derivation script writes."""
    parts: list[ConvexPart] = []
    index_of: dict[tuple[str, int], int] = {}
    for link in doc["links"]:
        body = LINK_NAMES.index(link["name"])
        for k, part in enumerate(link["parts"]):
            index_of[(link["name"], k)] = len(parts)
            parts.append(
                ConvexPart(
                    body,
                    k,
                    np.asarray(part["vertices_m"], float).reshape(-1, 3),
                    np.asarray(part["faces"], int).reshape(-1, 3),
                    float(part["volume_m3"]),
                )
            )
    bounds: dict[tuple[int, int], float] = {}
    joint_max: dict[tuple[int, int], float] = {}
    for pair in doc["self_collision"]["pairs"]:
        a = index_of[(pair["a"][0], pair["a"][1])]
        b = index_of[(pair["b"][0], pair["b"][1])]
        key = (min(a, b), max(a, b))
        if pair["adjacent"]:
            joint_max[key] = float(pair["max_sampled_m"])
        bound = pair["lower_bound_m"]
        bounds[key] = -np.inf if bound is None else float(bound)
    return ArmGeometry(
        doc["model"],
        tuple(parts),
        bounds,
        joint_max,
        doc["source"],
        doc["over_approximation_mm"],
    )
