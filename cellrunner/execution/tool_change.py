"""The tool changer's two actions (steps of an expanded ``change_tool``).

``tool_unlock`` drops the changer's lock output (the mounted tool stays in the rack place
the arm stands at) and, with a ``locked`` input, waits for it to read false;
``tool_lock`` sets the lock and waits for ``locked`` to read true. After the lock the
context's gripper channels are the new tool's; between the two, none.
"""

from __future__ import annotations

from collections.abc import Generator

from cellrunner.execution.context import JobContext, use_gripper
from cellrunner.execution.outcome import OK, Outcome
from cellrunner.model.codes import ResultCode
from cellrunner.model.expand import Step

#: without a ``locked`` input the changer is given this long to act (s)
UNCONFIRMED_S = 0.15


def run_tool_unlock(ctx: JobContext, step: Step) -> Generator[None, None, Outcome]:
    outcome = yield from _drive(ctx, step, lock=False)
    if outcome.ok:
        use_gripper(ctx, None)
        ctx.tool_mass_kg = 0.0
        tcp_of = ctx.tools[step.extra["tcp_of"]]
        ctx.backend.set_tool(tcp_of.tcp.matrix(), 0.0, (0.0, 0.0, 0.0))  # the bare flange
    return outcome


def run_tool_lock(ctx: JobContext, step: Step) -> Generator[None, None, Outcome]:
    outcome = yield from _drive(ctx, step, lock=True)
    if outcome.ok:
        tool = ctx.tools[step.extra["tool"]]
        use_gripper(ctx, tool.gripper)
        ctx.tool_mass_kg = tool.payload.mass
        ctx.backend.set_tool(tool.tcp.matrix(), tool.payload.mass, tool.payload.cog_m)
    return outcome


def _drive(ctx: JobContext, step: Step, lock: bool) -> Generator[None, None, Outcome]:
    lock_channel = ctx.outputs[step.extra["lock_output"]]
    ctx.backend.set_output(lock_channel, lock)
    args = step.args
    t0 = ctx.now_s
    if args.confirm is None:
        while ctx.now_s - t0 < UNCONFIRMED_S:
            yield
        return OK
    channel = ctx.inputs[args.confirm]
    while bool(ctx.last_state.inputs.get(channel)) != lock:
        if ctx.now_s - t0 >= args.timeout:
            what = "lock" if lock else "release"
            return Outcome.failed(
                ResultCode.STEP_TIMEOUT,
                f"the tool changer did not {what} tool "
                f"{step.name!r}: {args.confirm} not {str(lock).lower()} within {args.timeout:g} s",
            )
        yield
    return OK
