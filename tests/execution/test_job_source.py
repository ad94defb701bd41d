"""A request's source says whether its client job ids name jobs (:class:`JobSource`): the
engine dedupes on that property, never on a protocol's name."""

from __future__ import annotations

from cellrunner.model.cellport import JobSource
from cellrunner.model.codes import ResultCode
from cellrunner.plc.modbus import SOURCE as MODBUS_SOURCE
from cellrunner.plc.opcua import SOURCE as OPCUA_SOURCE
from tests.execution.fakes import make_cell


def test_a_plain_name_is_a_spec_requester_or_one_whose_ids_do_not_name_jobs() -> None:
    assert JobSource.of("opcua") == OPCUA_SOURCE and OPCUA_SOURCE.ids_name_jobs
    assert JobSource.of("modbus") == MODBUS_SOURCE and not MODBUS_SOURCE.ids_name_jobs
    assert JobSource.of("cli") == JobSource("cli", ids_name_jobs=False)
    mes = JobSource("mes", ids_name_jobs=True)
    assert JobSource.of(mes) is mes


def test_any_requester_whose_ids_name_jobs_gets_the_first_job_again(tmp_path) -> None:
    cell, _ = make_cell(tmp_path)
    mes = JobSource("mes", ids_name_jobs=True)
    first = cell.start_job("pick_place", {}, "order-7", mes)
    again = cell.start_job("pick_place", {}, "order-7", mes)
    assert first.accepted and again.accepted and again.job_id == first.job_id
    (record,) = cell.journal.last(10)
    assert (record.source, record.client_job_id) == ("mes", "order-7")


def test_a_requester_whose_ids_do_not_name_jobs_asks_for_a_second_job(tmp_path) -> None:
    cell, _ = make_cell(tmp_path)
    assert cell.start_job("pick_place", {}, "dry-run", "cli").accepted
    again = cell.start_job("pick_place", {}, "dry-run", "cli")
    assert again.reject_code == ResultCode.REJECT_NOT_READY  # a second job, while one runs
