"""The twin's infeed before a job: a new part from the feed (:mod:`.feed`), or, without
one, the parts that were moved put back at their spawn poses."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from cellrunner.sim.mujoco_loader import load_mujoco

if TYPE_CHECKING:
    from cellrunner.sim.belts import Belts
    from cellrunner.sim.depth import Intruders
    from cellrunner.sim.feed import Feeder
    from cellrunner.sim.tool_changer import ToolChanger
    from cellrunner.sim.vacuum import VacuumCups


def feed_parts(world: Any, moved_m: float = 0.01) -> list[str]:
    """See :meth:`~cellrunner.sim.world.SimWorld.feed_parts`."""
    from scipy.spatial.transform import Rotation

    if world.feeder is not None:
        new = world.feeder.feed()
        return [new] if new is not None else []
    mujoco = load_mujoco()
    fed = []
    for part in world.description.parts:
        if part.name in world._gripped:
            continue
        spawn = part.T_world_part
        if np.linalg.norm(world.part_pose_world(part.name)[:3, 3] - spawn[:3, 3]) <= moved_m:
            continue
        adr = world.ids.part_qpos[part.name]
        x, y, z, w = Rotation.from_matrix(spawn[:3, :3]).as_quat()
        world.data.qpos[adr : adr + 7] = [*spawn[:3, 3], w, x, y, z]
        dof = world.model.jnt_dofadr[world.model.joint(f"part:{part.name}").id]
        world.data.qvel[dof : dof + 6] = 0.0
        fed.append(part.name)
    if fed:
        mujoco.mj_forward(world.model, world.data)
    return fed


def attach_equipment(
    world: Any,
) -> tuple[VacuumCups | None, Intruders | None, ToolChanger | None, Belts | None, Feeder | None]:
    """The optional parts of a built SimWorld, each None when the cell has none: its
    vacuum cups, intruders, tool changer, belts and feeder. Each is set on ``world`` as
    it is made, since a later one may look at an earlier one (the tool changer at the
    cups)."""
    d = world.description
    vacuum: VacuumCups | None = None
    if d.vacuum is not None:
        from cellrunner.sim.vacuum import VacuumCups

        vacuum = VacuumCups(world, d.vacuum)
    world.vacuum = vacuum
    intruders: Intruders | None = None
    if d.intruders:
        from cellrunner.sim.depth import Intruders

        intruders = Intruders(world.model, world.data, d.intruders)
    world.intruders = intruders
    changer: ToolChanger | None = None
    if d.tool_changer is not None:
        from cellrunner.sim.tool_changer import ToolChanger

        changer = ToolChanger(world, d.tool_changer)
    world.changer = changer
    belts: Belts | None = None
    if d.belts:
        from cellrunner.sim.belts import Belts

        belts = Belts(world.model, world.data, d.belts, world.period_s)
    world.belts = belts
    feeder: Feeder | None = None
    if d.feed is not None:
        from cellrunner.sim.feed import Feeder

        feeder = Feeder(world, d.feed)
    return vacuum, intruders, changer, belts, feeder
