"""Cameras of a cell (``cameras:``, an extension of SPEC section 3): intrinsics, image size,
where the camera is mounted, and the calibration board it is calibrated against.

Frames (OpenCV's, as every vision library reports poses):

- **camera frame**: origin at the optical centre, Z out of the lens along the optical axis,
  X to the right of the image, Y down it. ``pose`` places this frame in the mount: the
  world, a named frame, or the flange (tool0, the frame ``tool.tcp`` is given in).
- **board frame**: origin at the centre of the printed face, Z out of that face (towards
  the camera that sees it), X along the ``squares[0]`` direction, Y along ``squares[1]``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from cellrunner.model.base import Name, Pose, Strict
from cellrunner.model.units import PositiveLength

if TYPE_CHECKING:
    import numpy as np

#: ArUco dictionaries a board may use (OpenCV's predefined ones)
DICTIONARIES = tuple(
    f"DICT_{bits}X{bits}_{n}" for bits in (4, 5, 6, 7) for n in (50, 100, 250, 1000)
)
# a Literal of the names above: pydantic reads it at run time; to mypy it is no type
Dictionary = Literal[DICTIONARIES]  # type: ignore[valid-type]
#: mounts that are not frames: the world, and the arm's flange (moves with the arm)
FLANGE, WORLD = "flange", "world"


class Intrinsics(Strict):
    """Pinhole intrinsics in pixels and OpenCV's distortion coefficients."""

    fx: float = Field(gt=0)
    """Focal length along the image's X, px. Example: `600`"""
    fy: float = Field(gt=0)
    """Focal length along the image's Y, px. Example: `600`"""
    cx: float
    """Principal point, image X, px. Example: `320`"""
    cy: float
    """Principal point, image Y, px. Example: `240`"""
    distortion: Annotated[list[float], Field(max_length=14)] = Field(default_factory=list)
    """OpenCV distortion coefficients k1 k2 p1 p2 [k3 ...] (none: an ideal lens). Example: `[0.05, -0.1, 0, 0, 0]`"""

    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix K."""
        import numpy as np

        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


class Board(Strict):
    """A ChArUco calibration board (OpenCV's aruco module)."""

    squares: Annotated[list[Annotated[int, Field(ge=3, le=40)]], Field(min_length=2, max_length=2)]
    """Chessboard squares along the board's X and Y. Example: `[7, 5]`"""
    square: PositiveLength
    """Edge of one chessboard square, m. Example: `0.03`"""
    marker: PositiveLength
    """Edge of one ArUco marker (inside a white square), m. Example: `0.022`"""
    dictionary: Dictionary = "DICT_4X4_50"
    """ArUco dictionary of the markers. Example: `DICT_4X4_50`"""
    mount: Name = WORLD
    """Where the board is fixed: world, a frame, or flange (on the arm: a camera fixed in the world is calibrated so). Example: `world`"""
    pose: Pose = Field(default_factory=Pose)
    """The board frame (centre of the printed face, Z out of it) in its mount, m and deg; nominal, calibration measures it. Example: `{xyz: [0.6, 0, 0.85], rpy: [0, 0, 0]}`"""

    @model_validator(mode="after")
    def _fits(self) -> Board:
        if self.marker >= self.square:
            raise PydanticCustomError(
                "board",
                f"marker {self.marker:g} m must be smaller than square {self.square:g} m",
            )
        markers = self.squares[0] * self.squares[1] // 2
        size = int(self.dictionary.rsplit("_", 1)[1])
        if markers > size:
            raise PydanticCustomError(
                "board",
                f"a {self.squares[0]} x {self.squares[1]} board has {markers} markers; "
                f"{self.dictionary} has only {size}",
            )
        return self

    @property
    def size_m(self) -> tuple[float, float]:
        """Width (along X) and height (along Y) of the checkered area, m."""
        return self.squares[0] * self.square, self.squares[1] * self.square


class Depth(Strict):
    """A depth camera's range and rate (SPEC section 12): depth images in metres along the
    camera frame's Z; pixels nearer than ``range[0]`` or farther than ``range[1]`` carry no
    depth."""

    range: Annotated[list[PositiveLength], Field(min_length=2, max_length=2)] = Field(
        default_factory=lambda: [0.3, 2.5]
    )
    """Nearest and farthest depth the camera measures, m. Example: `[0.3, 2.5]`"""
    rate: float = Field(default=15.0, gt=0, le=120)
    """Depth images per second, Hz. Example: `15`"""

    @model_validator(mode="after")
    def _ordered(self) -> Depth:
        near, far = self.range
        if not near < far:
            raise PydanticCustomError(
                "depth", f"range [{near:g}, {far:g}] m must have its near end below its far end"
            )
        return self

    @property
    def range_m(self) -> tuple[float, float]:
        return self.range[0], self.range[1]


class Camera(Strict):
    """A camera: intrinsics, image size, mount and pose; optionally its calibration board
    and depth."""

    intrinsics: Intrinsics
    """Pinhole intrinsics (px) and distortion. Example: `{fx: 600, fy: 600, cx: 320, cy: 240}`"""
    image_size: Annotated[
        list[Annotated[int, Field(ge=16, le=16384)]], Field(min_length=2, max_length=2)
    ]
    """Image width and height, px. Example: `[640, 480]`"""
    mount: Name = WORLD
    """What carries the camera: world, a frame, or flange (eye-in-hand). Example: `flange`"""
    pose: Pose = Field(default_factory=Pose)
    """The camera frame (OpenCV: Z out of the lens, X right, Y down) in its mount, m and deg; `calibrate-camera` writes it. Example: `{xyz: [0.06, 0, 0.04], rpy: [0, 0, 90]}`"""
    board: Board | None = None
    """The calibration board `calibrate-camera` uses. Example: `{squares: [7, 5], square: 0.03, marker: 0.022, pose: {xyz: [0.6, 0, 0.85]}}`"""
    depth: Depth | None = None
    """A depth camera: the range it measures (m) and its rate (Hz); it then gives depth images in metres. Example: `{range: [0.3, 2.5], rate: 15}`"""

    @model_validator(mode="after")
    def _board_opposite(self) -> Camera:
        if self.board is not None and (self.board.mount == FLANGE) == (self.mount == FLANGE):
            where = "on the flange" if self.mount == FLANGE else "off the arm"
            raise PydanticCustomError(
                "camera",
                f"camera and board are both {where}; hand-eye calibration needs one on the "
                "flange and the other fixed (board mount: "
                + ("world or a frame)" if self.mount == FLANGE else "flange)"),
            )
        return self

    @property
    def eye_in_hand(self) -> bool:
        return self.mount == FLANGE
