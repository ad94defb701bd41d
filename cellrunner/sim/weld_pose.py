"""Welding a part to the tool where it is now: the equality constraint a gripper's hold
uses in the twin (the cups' seal, sim/vacuum.py; the jaws' friction, sim/jaw_welds.py)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from cellrunner.sim.description import PartDescription


def weld_where_it_is(mj: Any, model: Any, data: Any, eq: int, tool: int, part: int) -> None:
    """Activate weld ``eq`` holding body ``part`` to body ``tool`` at their current
    relative pose (no pull towards another one)."""
    weld_at(model, data, eq, relative_pose(mj, data, tool, part))


def relative_pose(mj: Any, data: Any, tool: int, part: int) -> np.ndarray:
    """Body ``part``'s pose in body ``tool``'s frame now: position (3) then quaternion
    (4), as a weld's ``eq_data`` holds it."""
    R_tool = data.xmat[tool].reshape(3, 3)
    R_part = data.xmat[part].reshape(3, 3)
    quat = np.zeros(4)
    mj.mju_mat2Quat(quat, (R_tool.T @ R_part).ravel())
    return np.concatenate([R_tool.T @ (data.xpos[part] - data.xpos[tool]), quat])


def weld_at(model: Any, data: Any, eq: int, pose: np.ndarray) -> None:
    """Activate weld ``eq`` holding its part at ``pose`` (:func:`relative_pose`) in its
    tool's frame: where the part is now, or where it sat earlier (it is pulled there)."""
    model.eq_data[eq, 0:3] = 0.0
    model.eq_data[eq, 3:6] = pose[:3]
    model.eq_data[eq, 6:10] = pose[3:7]
    model.eq_data[eq, 10] = 1.0
    data.eq_active[eq] = 1


def add_tool_welds(
    root: ET.Element, parts: Iterable[PartDescription], prefix: str, **attrs: str
) -> None:
    """One inactive weld per part, tool to part, named ``prefix`` + the part's name, with
    the constraint's ``attrs`` (solref, solimp) (MJCF)."""
    eq = root.find("equality")
    if eq is None:
        eq = ET.SubElement(root, "equality")
    for part in parts:
        weld = {"name": f"{prefix}{part.name}", "body1": "tool", "body2": f"part:{part.name}"}
        ET.SubElement(eq, "weld", {**weld, "active": "false", **attrs})
