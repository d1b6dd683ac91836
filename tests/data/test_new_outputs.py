"""Outputs named only when complete (rig.data.output_folder.new_file, new_folder): a failure leaves nothing, an
existing path is never written over."""

import pytest

from rig.data.output_folder import new_file, new_folder


def test_a_failed_body_leaves_no_file_and_no_temporary(tmp_path):
    with pytest.raises(KeyboardInterrupt), new_file(tmp_path / "out.json") as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_a_file_that_appeared_meanwhile_is_not_written_over(tmp_path):
    out = tmp_path / "out.json"
    with pytest.raises(FileExistsError), new_file(out) as tmp:
        tmp.write_text("new")
        out.write_text("someone else's")
    assert out.read_text() == "someone else's" and list(tmp_path.iterdir()) == [out]


def test_a_folder_is_named_when_complete_and_not_before(tmp_path):
    out = tmp_path / "sub" / "figures"
    with new_folder(out) as folder:
        (folder / "a.png").write_bytes(b"png")
        assert not out.exists()
    assert [p.name for p in out.iterdir()] == ["a.png"] and [p.name for p in out.parent.iterdir()] == ["figures"]


def test_a_failed_folder_leaves_nothing_and_an_empty_target_stays(tmp_path):
    out = tmp_path / "figures"
    out.mkdir()
    with pytest.raises(ValueError), new_folder(out) as folder:
        (folder / "a.png").write_bytes(b"png")
        raise ValueError("drawing failed")
    assert [p.name for p in tmp_path.iterdir()] == ["figures"] and list(out.iterdir()) == []
