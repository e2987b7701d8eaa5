"""Tests for facecap.io._atomic: all-or-nothing file writes."""

from __future__ import annotations

import pytest

from facecap.errors import InputError
from facecap.io._atomic import atomic_folder, atomic_path, atomic_write_text


def _leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if ".partial-" in p.name)


def test_success_renames_onto_final_and_leaves_nothing_else(tmp_path):
    final = tmp_path / "take.c3d"
    with atomic_path(final) as tmp:
        assert tmp.parent == tmp_path
        assert tmp.name.startswith(".take.c3d.partial-")
        assert tmp.suffix == ".c3d"  # writers that pick the format by suffix still work
        assert not final.exists()  # nothing appears under the final name while writing
        tmp.write_bytes(b"payload")
    assert final.read_bytes() == b"payload"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.c3d"]


def test_exception_leaves_no_final_file_and_no_temp_file(tmp_path):
    final = tmp_path / "out.txt"
    with pytest.raises(RuntimeError, match="boom"):
        with atomic_path(final) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert not final.exists()
    assert list(tmp_path.iterdir()) == []


def test_exception_keeps_the_previous_file_intact(tmp_path):
    final = tmp_path / "out.txt"
    final.write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(final) as tmp:
            tmp.write_text("new, unfinished")
            raise KeyboardInterrupt
    assert final.read_text() == "old"
    assert _leftovers(tmp_path) == []


def test_success_replaces_an_existing_file(tmp_path):
    final = tmp_path / "out.txt"
    final.write_text("old")
    with atomic_path(final) as tmp:
        tmp.write_text("new")
    assert final.read_text() == "new"
    assert _leftovers(tmp_path) == []


def test_block_that_writes_nothing_raises_and_leaves_nothing(tmp_path):
    final = tmp_path / "out.txt"
    with pytest.raises(FileNotFoundError):
        with atomic_path(final):
            pass
    assert list(tmp_path.iterdir()) == []


def test_suffix_override_and_unique_names(tmp_path):
    final = tmp_path / "take.C3D"
    with atomic_path(final, suffix=".c3d") as a, atomic_path(tmp_path / "take.C3D", suffix=".c3d") as b:
        assert a.name.endswith(".c3d") and a != b
        a.write_text("a")
        b.write_text("b")
    assert final.read_text() == "a"  # the outer block finished last
    assert _leftovers(tmp_path) == []


def test_missing_directory_or_directory_target_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="does not exist") as info:
        with atomic_path(tmp_path / "nope" / "out.txt"):
            pass  # pragma: no cover
    assert info.value.path == str(tmp_path / "nope" / "out.txt")
    with pytest.raises(InputError, match="directory"):
        with atomic_path(tmp_path):
            pass  # pragma: no cover


def test_atomic_write_text_writes_exact_text(tmp_path):
    text = "line one\r\nline two\nünïcode ✓\n"
    atomic_write_text(tmp_path / "t.txt", text)
    assert (tmp_path / "t.txt").read_bytes() == text.encode("utf-8")
    atomic_write_text(tmp_path / "t.txt", "x", encoding="latin-1")
    assert (tmp_path / "t.txt").read_text() == "x"
    assert _leftovers(tmp_path) == []


def test_atomic_write_text_failure_leaves_nothing(tmp_path):
    with pytest.raises(UnicodeEncodeError):
        atomic_write_text(tmp_path / "t.txt", "✓", encoding="ascii")
    assert list(tmp_path.iterdir()) == []


def _hidden(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_atomic_folder_replaces_an_earlier_result_and_leaves_no_staging(tmp_path):
    final = tmp_path / "result"
    for payload in ("first", "second"):
        with atomic_folder(final, marker_file="done.json") as stage:
            assert stage.parent == tmp_path and stage.name.startswith(".result.partial-")
            (stage / "data.txt").write_text(payload)
            (stage / "done.json").write_text("{}")
        assert (final / "data.txt").read_text() == payload
        assert sorted(p.name for p in final.iterdir()) == ["data.txt", "done.json"]
    assert [p.name for p in tmp_path.iterdir()] == ["result"]


def test_atomic_folder_keeps_the_earlier_result_when_the_block_fails(tmp_path):
    final = tmp_path / "result"
    final.mkdir()
    (final / "done.json").write_text("old")
    with pytest.raises(RuntimeError, match="boom"):
        with atomic_folder(final, marker_file="done.json") as stage:
            (stage / "done.json").write_text("new, unfinished")
            raise RuntimeError("boom")
    assert (final / "done.json").read_text() == "old"
    assert _hidden(tmp_path) == []


def test_atomic_folder_without_its_marker_is_not_finished(tmp_path):
    final = tmp_path / "result"
    with pytest.raises(InputError, match="done.json missing"):
        with atomic_folder(final, marker_file="done.json") as stage:
            (stage / "data.txt").write_text("half")
    assert list(tmp_path.iterdir()) == []


def test_atomic_folder_refuses_a_foreign_folder_or_a_file(tmp_path):
    foreign = tmp_path / "photos"
    foreign.mkdir()
    (foreign / "holiday.jpg").write_bytes(b"jpeg")
    with pytest.raises(InputError, match="holds no done.json") as info:
        with atomic_folder(foreign, marker_file="done.json"):
            pass  # pragma: no cover
    assert info.value.path == str(foreign)
    assert (foreign / "holiday.jpg").read_bytes() == b"jpeg"
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        with atomic_folder(tmp_path / "file", marker_file="done.json"):
            pass  # pragma: no cover
    assert _hidden(tmp_path) == []
