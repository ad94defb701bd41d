"""``dry-run --record FILE.rrd|FILE.mcap`` of the demo cell, read back: Rerun's own reader
for the .rrd, the mcap reader (and Foxglove's protobuf schemas) for the .mcap."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from cellrunner.cli.main import main
from tests.conftest import DEMO_CELL, PICK_PLACE
from tests.record.record_rig import rrd_columns

ARM_LINKS = [f"/world/link{i}" for i in range(1, 7)]


def _dry_run(target: Path) -> None:
    rc = main(["dry-run", str(DEMO_CELL), str(PICK_PLACE), "--json", "--record", str(target)])
    assert rc == 0
    assert target.stat().st_size > 10_000


def test_rrd_holds_the_scene_moving_on_one_timeline(tmp_path: Path) -> None:
    target = tmp_path / "job.rrd"
    _dry_run(target)
    components, moves = rrd_columns(target)
    for link in ARM_LINKS:  # the arm as meshes, each in its link's frame, moving
        assert any(
            "Mesh3D:vertex_positions" in components[p]
            for p in components
            if p.startswith(link + "/")
        )
        change = np.ptp(np.array(moves[link]), axis=0)  # over the job: m, then rotation entries
        assert change.max() > 0.2, (link, change)
    assert "Mesh3D:triangle_indices" in components["/world/static/fixture_table"]
    part = np.array(moves["/world/part_block"])[:, :3]  # the part moves with the gripper
    assert np.linalg.norm(part[-1] - part[0]) > 0.1
    for path in ("/world/paths/planned", "/world/paths/measured"):
        assert "LineStrips3D:strips" in components[path]
    assert "TextLog:text" in components["/steps"]
    from rerun.chunk import RrdReader

    assert RrdReader(target).blueprints()  # opens laid out: the cell, the plots, the log
    for plot in (
        "/plots/wrist/force_N",
        "/plots/step",
        "/plots/joints/q1_rad",
        "/plots/io/gripper_close",
    ):
        assert "Scalars:scalars" in components[plot], plot


class _JsonDecoders:
    """The mcap reader's decoder factory for the JSON channels."""

    def decoder_for(self, encoding: str, schema: object) -> object:
        return json.loads if encoding == "json" else None


def test_mcap_is_foxglove_schemas_in_time_order(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    target = tmp_path / "job.mcap"
    _dry_run(target)
    with target.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory(), _JsonDecoders()])
        summary = reader.get_summary()
        assert summary is not None
        schemas = {s.name for s in summary.schemas.values()}
        assert {"foxglove.FrameTransforms", "foxglove.SceneUpdate", "foxglove.Log"} <= schemas
        topics = {c.topic: c for c in summary.channels.values()}
        assert {"/tf", "/scene", "/paths", "/log", "/plots"} <= set(topics)
        counts = Counter()
        times, meshes, frames, logs, plots = [], 0, set(), [], []
        for _schema, channel, message, decoded in reader.iter_decoded_messages(
            log_time_order=False
        ):
            counts[channel.topic] += 1
            times.append(message.log_time)
            if channel.topic == "/scene":
                meshes += sum(len(e.triangles) for e in decoded.entities)
            elif channel.topic == "/tf":
                frames |= {t.child_frame_id for t in decoded.transforms}
            elif channel.topic == "/log":
                logs.append(decoded.message)
            elif channel.topic == "/plots":
                plots.append(decoded)
    assert times == sorted(times) and times[-1] - times[0] > 5e9  # the job's ~7 s, in order
    assert counts["/tf"] > 300 and counts["/plots"] > 300  # one of each per sample (50 Hz)
    assert meshes >= 8  # six arm links, the tool, the fixtures, the part
    assert {"link6", "tool", "part_block", "tcp"} <= frames
    assert any("grip" in line for line in logs) and any(
        "job" in line and "OK" in line for line in logs
    )
    assert {"joints.q1_rad", "wrist.force_N", "io.gripper_close"} <= set(plots[0])
    assert summary.statistics is not None and summary.statistics.message_count == sum(
        counts.values()
    )


@pytest.mark.parametrize("name", ["job.txt", "no/such/folder/job.rrd"])
def test_a_bad_record_target_is_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    rc = main(["dry-run", str(DEMO_CELL), str(PICK_PLACE), "--record", str(tmp_path / name)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and "--record" in err[0] and "Traceback" not in err[0]


def test_a_watched_cell_records_its_depth_images_and_obstacle_map(tmp_path: Path) -> None:
    from tests.conftest import ROOT

    target = tmp_path / "watched.rrd"
    cell, task = ROOT / "cells" / "watched_ur5e.yaml", ROOT / "tasks" / "pick_place_watched.yaml"
    assert main(["dry-run", str(cell), str(task), "--json", "--record", str(target)]) == 0
    components, moves = rrd_columns(target)
    assert "Points3D:positions" in components["/world/obstacles"]
    depth = [p for p in components if p.startswith("/cameras/") and p.endswith("/depth")]
    assert depth and all("DepthImage:buffer" in components[p] for p in depth)
    camera = "/world" + depth[0].removesuffix("/depth")  # the camera's pose in the scene
    assert len(moves[camera]) >= 5


def test_an_align_step_records_what_its_camera_saw(tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    from tests.conftest import ROOT

    target = tmp_path / "align.mcap"
    cell, task = ROOT / "cells" / "align_pick_ur10e.yaml", ROOT / "tasks" / "align_pick.yaml"
    assert main(["dry-run", str(cell), str(task), "--json", "--record", str(target)]) == 0
    with target.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        images = [
            decoded
            for _, channel, _, decoded in reader.iter_decoded_messages(
                topics=["/cameras/wrist/image"]
            )
        ]
    assert images  # each look of the align step
    for image in images:
        channels = {"rgb8": 3, "mono8": 1}[image.encoding]
        assert image.width > 100 and len(image.data) == image.height * image.width * channels
        assert (
            len(set(image.data[:: max(1, len(image.data) // 5000)])) > 10
        )  # a picture, not a blank
