"""Shared pydantic pieces: the strict base model, poses, shapes."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.units import Angle, Length, PositiveLength

if TYPE_CHECKING:
    import numpy as np

    from cellrunner.model import geometry

Vec3 = Annotated[list[Length], Field(min_length=3, max_length=3)]
Rpy = Annotated[list[Angle], Field(min_length=3, max_length=3)]
Name = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_\-]*$", min_length=1, max_length=64)]


class Strict(BaseModel):
    """Base of every file model: unknown keys are errors, values are not coerced loosely."""

    # a field's docstring is its schema description: read by cellrunner.model.schema when
    # a schema is generated, not here (use_attribute_docstrings parses every class's source
    # at import, ~45 ms of every command's start)
    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)


class Pose(Strict):
    """A pose: translation ``xyz`` in m, XYZ fixed-axis ``rpy`` in degrees."""

    xyz: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    """Translation x, y, z in m (or strings with a unit). Example: `[0.4, 0, 0.9]`"""
    rpy: Rpy = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    """Rotation as XYZ fixed-axis roll, pitch, yaw in degrees. Example: `[180, 0, 90]`"""

    def matrix(self) -> np.ndarray:
        from cellrunner.model.geometry import pose_matrix  # numpy: not for `validate`

        return pose_matrix(self.xyz, self.rpy)


class BoxShape(Strict):
    size: Annotated[list[PositiveLength], Field(min_length=3, max_length=3)]
    """Edge lengths along x, y, z in m. Example: `[1.2, 0.8, 0.04]`"""


class CylinderShape(Strict):
    radius: PositiveLength
    """Radius in m. Example: `0.05`"""
    length: PositiveLength
    """Length along the local Z axis in m, centred on the pose. Example: `0.6`"""


class SphereShape(Strict):
    radius: PositiveLength
    """Radius in m. Example: `0.05`"""


class MeshShape(Strict):
    file: str
    """STL file, relative to the project folder. Example: `meshes/fence.stl`"""
    scale: float = Field(default=1.0, gt=0)
    """Factor applied to the mesh's coordinates (0.001 for a mesh drawn in mm). Example: `0.001`"""


SHAPE_KEYS = ("box", "cylinder", "sphere", "mesh")


class Shaped(Strict):
    """Something with exactly one of ``box``, ``cylinder``, ``sphere``, ``mesh``."""

    box: BoxShape | None = None
    """A box centred on the pose. Example: `{size: [1.2, 0.8, 0.04]}`"""
    cylinder: CylinderShape | None = None
    """A cylinder along the pose's Z axis, centred on it. Example: `{radius: 0.05, length: 0.6}`"""
    sphere: SphereShape | None = None
    """A sphere centred on the pose. Example: `{radius: 0.05}`"""
    mesh: MeshShape | None = None
    """A triangle mesh (STL). Example: `{file: meshes/fence.stl}`"""

    @model_validator(mode="after")
    def _one_shape(self) -> Shaped:
        given = [k for k in SHAPE_KEYS if getattr(self, k) is not None]
        if len(given) != 1:
            what = "none" if not given else ", ".join(given)
            raise PydanticCustomError(
                "shape", f"needs exactly one shape of box, cylinder, sphere, mesh; got {what}"
            )
        return self

    @property
    def shape_key(self) -> str:
        return next(k for k in SHAPE_KEYS if getattr(self, k) is not None)

    def to_shape(self, resolve: Callable[[str], Path]) -> geometry.Shape:
        """The neutral geometry shape; ``resolve(str) -> Path`` locates mesh files."""
        from cellrunner.model import geometry

        if self.box:
            x, y, z = self.box.size
            return geometry.Box((x, y, z))
        if self.cylinder:
            return geometry.Cylinder(self.cylinder.radius, self.cylinder.length)
        if self.sphere:
            return geometry.Sphere(self.sphere.radius)
        assert self.mesh is not None  # exactly one shape key is set (validated)
        return geometry.Mesh(resolve(self.mesh.file).resolve(), self.mesh.scale)


class PlacedShape(Shaped):
    """A shape with a pose, written either inline (``xyz``, ``rpy``) or as ``pose:``."""

    pose: Pose | None = None
    """Where the shape sits, as {xyz, rpy}; or write xyz/rpy directly. Example: `{xyz: [0.4, 0, 0.88]}`"""
    xyz: Vec3 | None = None
    """Translation in m (short form of pose.xyz). Example: `[0, 0, 0.075]`"""
    rpy: Rpy | None = None
    """Rotation in degrees, XYZ fixed axes (short form of pose.rpy). Example: `[0, 90, 0]`"""

    @model_validator(mode="after")
    def _one_pose_form(self) -> PlacedShape:
        if self.pose is not None and (self.xyz is not None or self.rpy is not None):
            raise PydanticCustomError(
                "pose", "give the pose either as 'pose: {xyz, rpy}' or as 'xyz'/'rpy', not both"
            )
        return self

    def matrix(self) -> np.ndarray:
        if self.pose is not None:
            return self.pose.matrix()
        from cellrunner.model.geometry import pose_matrix

        return pose_matrix(self.xyz or (0, 0, 0), self.rpy or (0, 0, 0))


def plain(value: Any) -> Any:
    """JSON-able view of a model value (for hashing and reports)."""
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json")
    return value
