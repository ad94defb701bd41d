"""One lookup rule for every file a cell names: project folder, then the cell file's
folder, then the working directory (README, "A cell")."""

from __future__ import annotations

from cellrunner.model.load import load_cell, serve_file_warnings
from cellrunner.plc.opcua import OpcUaConfig
from tests.rig import CELL

OPCUA = (
    "plc:\n  opcua: {endpoint: 'opc.tcp://127.0.0.1:4840/x', users: opcua-users.yaml, pki: pki}\n"
)


def _project(tmp_path, users_in: str | None):
    (tmp_path / "cells").mkdir()
    cell = tmp_path / "cells" / "c.yaml"
    cell.write_text(CELL + OPCUA)
    if users_in is not None:
        (tmp_path / users_in).mkdir(exist_ok=True)
        (tmp_path / users_in / "opcua-users.yaml").write_text("{}\n")
    return load_cell(cell)


def test_users_file_beside_the_cell_file_is_found(tmp_path):
    cell = _project(tmp_path, "cells")
    assert serve_file_warnings(cell) == []
    config = OpcUaConfig.from_mapping(cell.cell.plc.opcua, resolve=cell.resolve)
    assert config.users_file == tmp_path / "cells" / "opcua-users.yaml"
    assert config.pki_dir == tmp_path / "pki"  # absent: created under the project folder


def test_project_folder_wins_and_a_missing_users_file_warns_only_for_serve(tmp_path):
    cell = _project(tmp_path, ".")
    config = OpcUaConfig.from_mapping(cell.cell.plc.opcua, resolve=cell.resolve)
    assert config.users_file == tmp_path / "opcua-users.yaml"
    (tmp_path / "opcua-users.yaml").unlink()
    missing = load_cell(tmp_path / "cells" / "c.yaml")
    assert missing.warnings == []  # check and dry-run never need it
    [warning] = serve_file_warnings(missing)
    assert str(warning).endswith(
        ":25:58: warning: plc.opcua.users: users file 'opcua-users.yaml' does not exist yet; "
        "create it with 'cellrunner users add'"
    )
