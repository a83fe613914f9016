"""Resumable batches (slitcli.io.batch): what a re-run reuses and what it refuses."""

import json

import pytest

from slitcli import __version__
from slitcli.errors import SlitcliError
from slitcli.io.batch import FrameBatch


def test_same_manifest_resumes_and_keeps_finished_parts(tmp_path):
    b = FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    b.part_path(0).write_text("0,1\n")
    again = FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    assert again.is_done(0) and not again.is_done(1)


def test_other_settings_are_refused_unless_overwrite(tmp_path):
    FrameBatch(tmp_path, "detect", {"fusion": "paper"}).part_path(0).write_text("0,1\n")
    with pytest.raises(SlitcliError, match=r"changed: fusion.*pass `overwrite`"):
        FrameBatch(tmp_path, "detect", {"fusion": "conservative"})
    b = FrameBatch(tmp_path, "detect", {"fusion": "conservative"}, overwrite=True)
    assert not b.is_done(0)


def test_results_of_another_slitcli_version_are_not_reused(tmp_path):
    b = FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    b.part_path(0).write_text("0,1\n")
    path = tmp_path / ".slitcli" / "detect" / "manifest.json"
    m = json.loads(path.read_text())
    assert m["slitcli_version"] == __version__
    path.write_text(json.dumps({**m, "slitcli_version": "0.0.1"}))
    with pytest.raises(SlitcliError, match="changed: slitcli_version"):
        FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    assert not FrameBatch(tmp_path, "detect", {"fusion": "paper"}, overwrite=True).is_done(0)
