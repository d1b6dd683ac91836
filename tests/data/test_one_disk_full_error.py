"""One DiskFullError (issue 32): the writer raises the class rig.data.dataset_format defines, so that an
`except DiskFullError` (or `except DatasetError`, as `rig run` catches a folder it cannot start) written against
the dataset contract catches a real full disk. Before, the writer raised a twin of its own that only the
parent class caught."""

import errno
import os

import pytest

from rig.data import append_log, dataset_format
from rig.data.dataset_writer import DatasetWriter


def no_space(fd, data):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_full_disk_at_the_start_is_the_contracts_disk_full_error(tmp_path, monkeypatch):
    monkeypatch.setattr(append_log, "write_all", no_space)
    try:
        DatasetWriter(tmp_path / "ds", {"campaign": {"name": "x"}})
    except dataset_format.DiskFullError as exc:
        assert "nothing was written" in str(exc)
    else:
        pytest.fail("the writer started on a full disk")


def test_a_full_disk_during_the_run_is_the_contracts_disk_full_error(tmp_path, monkeypatch):
    writer = DatasetWriter(tmp_path / "ds", {"campaign": {"name": "x"}})
    monkeypatch.setattr(append_log, "write_all", no_space)
    with pytest.raises(dataset_format.DiskFullError, match="the disk is full"):
        writer.event("point")
    writer.close()
