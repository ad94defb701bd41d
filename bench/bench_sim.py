"""Benchmark of the MuJoCo twin: real-time factor and tracking error of a pick and place.

Streams a ~10 s pick/place cycle of the demo cell (approach, descend, grip, lift,
transfer, place, release, retreat, home) through SimBackend exactly as the engine does:
``servo`` + ``wait_period`` + ``read_state`` every controller period, gripper output
and dwell times included. Real-time factor = simulated seconds / wall seconds of that
loop (model build excluded). Tracking error = TCP distance between each set-point and
the measured pose at the end of its period (computed after the timed loop).

    PYTHONPATH=. python bench/bench_sim.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np

from cellrunner.backends.sim.backend import SimBackend
from cellrunner.model.robots import robot_spec
from cellrunner.model.trajectory import ApprovedTrajectory, approve
from cellrunner.sim import demo
from cellrunner.sim.description import TwinDescription, dh_forward
from cellrunner.sim.mjcf import PhysicsOptions


@dataclass
class Segment:
    name: str
    trajectory: ApprovedTrajectory | None  # None: a dwell with the gripper output below
    dwell_s: float = 0.0
    gripper_closed: bool | None = None


def pick_place_program(desc: TwinDescription) -> list[Segment]:
    rate = desc.rate_hz
    cube = np.array(demo.CUBE_XYZ_M) + (0, 0, 0.005)
    place = np.array([0.40, 0.30, 0.93])
    q = np.array(desc.q_home_rad)
    program: list[Segment] = []  # durations keep every joint under 180 deg/s (UR5e)

    def move(name: str, xyz: np.ndarray | None, duration_s: float) -> None:
        nonlocal q
        q_to = (
            np.array(desc.q_home_rad)
            if xyz is None
            else demo.solve_ik(desc, demo.tcp_down_at(xyz), q)
        )
        samples = demo.quintic_blend(q, q_to, duration_s, rate)
        program.append(
            Segment(name, approve(demo.to_trajectory(samples, rate), len(program), name))
        )
        q = q_to

    move("approach", cube + (0, 0, 0.10), 1.8)
    move("descend", cube, 0.6)
    program.append(Segment("grip", None, 0.5, True))
    move("lift", cube + (0, 0, 0.15), 0.7)
    move("transfer", place + (0, 0, 0.15), 1.8)
    move("descend", place + (0, 0, 0.002), 0.7)
    program.append(Segment("release", None, 0.5, False))
    move("retreat", place + (0, 0, 0.10), 0.6)
    move("home", None, 2.4)
    return program


def run(desc: TwinDescription, options: PhysicsOptions) -> dict[str, float]:
    backend = SimBackend(desc, options)
    t0 = time.perf_counter()
    backend.connect()
    build_s = time.perf_counter() - t0
    program = pick_place_program(desc)
    q_log: list[np.ndarray] = []
    ref_log: list[np.ndarray] = []
    sim0 = backend.sim_time_s
    cpu0 = time.process_time()
    wall0 = time.perf_counter()
    for seg in program:
        if seg.trajectory is None:
            backend.set_output("DO0", bool(seg.gripper_closed))
            for _ in range(round(seg.dwell_s * backend.rate_hz)):
                backend.wait_period()
                backend.read_state()
            continue
        for i in range(len(seg.trajectory.trajectory.q_rad)):
            backend.servo(seg.trajectory, i)
            backend.wait_period()
            state = backend.read_state()
            q_log.append(state.q_rad)
            ref_log.append(seg.trajectory.trajectory.q_rad[i])
    wall_s = time.perf_counter() - wall0
    cpu_s = time.process_time() - cpu0
    sim_s = backend.sim_time_s - sim0
    placed = backend.world.part_pose_world("cube")[:3, 3]
    backend.close()
    tcp = lambda q: (dh_forward(desc.spec, q) @ desc.T_flange_tcp)[:3, 3]  # noqa: E731
    err = np.array([np.linalg.norm(tcp(a) - tcp(r)) for a, r in zip(q_log, ref_log, strict=True)])
    return {
        "build_s": build_s,
        "sim_s": sim_s,
        "wall_s": wall_s,
        "rtf": sim_s / wall_s,
        "rtf_cpu": sim_s / cpu_s,
        "err_max_mm": 1e3 * err.max(),
        "err_rms_mm": 1e3 * float(np.sqrt((err**2).mean())),
        "place_err_mm": 1e3 * float(np.linalg.norm(placed[:2] - (0.40, 0.30))),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs per case; best RTF kept")
    args = parser.parse_args()
    cases = [
        ("ur5e 500 Hz, 2 ms step (default)", demo.demo_description(), PhysicsOptions()),
        ("ur5e 500 Hz, 1 ms step", demo.demo_description(), PhysicsOptions(max_timestep_s=0.001)),
        (
            "ur5e 500 Hz, 2 ms, pyramidal cone",
            demo.demo_description(),
            PhysicsOptions(cone="pyramidal", impratio=1.0),
        ),
        (
            "ur5 (CB3) 125 Hz, 4 x 2 ms",
            demo.demo_description(spec=robot_spec("ur5")),
            PhysicsOptions(),
        ),
    ]
    header = (
        f"{'case':36s} {'build s':>8s} {'sim s':>7s} {'wall s':>7s} {'RTF':>7s} {'RTF cpu':>7s} "
        f"{'err max mm':>10s} {'err rms mm':>10s} {'place mm':>9s}"
    )
    print(header)
    print("-" * len(header))
    for label, desc, options in cases:
        runs = [run(desc, options) for _ in range(args.repeat)]
        r = max(runs, key=lambda x: x["rtf"])
        print(
            f"{label:36s} {r['build_s']:8.3f} {r['sim_s']:7.2f} {r['wall_s']:7.3f} "
            f"{r['rtf']:7.1f} {r['rtf_cpu']:7.1f} {r['err_max_mm']:10.3f} {r['err_rms_mm']:10.3f} "
            f"{r['place_err_mm']:9.2f}"
        )
    print("\ntarget: RTF >= 50 (simulated s per wall s, build excluded); tracking error < 5 mm")
    print("RTF cpu: simulated s per CPU s of this process (robust when the machine is busy)")


if __name__ == "__main__":
    main()
