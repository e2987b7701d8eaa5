"""Tests for facecap.io.atomic_write: all-or-nothing file writes."""

from __future__ import annotations

import errno
import importlib
import os

import pytest

from facecap.errors import InputError
from facecap.io.atomic_write import (atomic_folder, atomic_path, atomic_write_text, check_file_destination,
                                     check_folder_destination, final_path, recorded_path, resolve_recorded_path)

atomic_module = importlib.import_module("facecap.io.atomic_write")  # the module, for patching what it calls


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
        with atomic_folder(final, marker_file="done.json", overwrite=payload == "second") as stage:
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
        with atomic_folder(final, marker_file="done.json", overwrite=True) as stage:
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
    with pytest.raises(InputError, match=r"is not a facecap result \(no done.json\)") as info:
        with atomic_folder(foreign, marker_file="done.json"):
            pass  # pragma: no cover
    assert info.value.path == str(foreign)
    assert (foreign / "holiday.jpg").read_bytes() == b"jpeg"
    with pytest.raises(InputError, match="even with --overwrite"):  # never deleted, whatever the caller says
        with atomic_folder(foreign, marker_file="done.json", overwrite=True):
            pass  # pragma: no cover
    assert (foreign / "holiday.jpg").read_bytes() == b"jpeg"
    (tmp_path / "file").write_text("x")
    for overwrite in (False, True):
        with pytest.raises(InputError, match="not a folder"):
            with atomic_folder(tmp_path / "file", marker_file="done.json", overwrite=overwrite):
                pass  # pragma: no cover
    assert (tmp_path / "file").read_text() == "x"
    assert _hidden(tmp_path) == []


def _finished(folder, *names):
    folder.mkdir()
    for name in names:
        (folder / name).write_text(name)


def test_an_earlier_result_is_refused_before_the_block_runs_and_loses_nothing(tmp_path):
    final = tmp_path / "result"
    _finished(final, "done.json", "data.txt", "performance.mdd")  # the mdd: an export the user made since
    entered = []
    with pytest.raises(InputError) as info:
        with atomic_folder(final, marker_file="done.json"):
            entered.append(True)  # pragma: no cover
    assert entered == []
    assert info.value.path == str(final) and "pass --overwrite" in str(info.value) and "\n" not in str(info.value)
    assert sorted(p.name for p in final.iterdir()) == ["data.txt", "done.json", "performance.mdd"]
    assert _hidden(tmp_path) == []
    with pytest.raises(InputError, match="pass --overwrite"):  # the check a job makes before its long work
        check_folder_destination(final, marker_file="done.json")
    check_folder_destination(final, marker_file="done.json", overwrite=True)


def test_a_result_that_appears_during_the_run_is_kept_and_so_is_the_run(tmp_path):
    final = tmp_path / "result"
    with pytest.raises(InputError) as info:
        with atomic_folder(final, marker_file="done.json") as stage:
            (stage / "done.json").write_text("this run")
            _finished(final, "done.json")  # another run finished first
    assert (final / "done.json").read_text() == "done.json"
    kept = tmp_path / "result-2"
    assert (kept / "done.json").read_text() == "this run" and str(kept) in str(info.value)
    assert info.value.path == str(final) and "pass --overwrite" in str(info.value)
    # a file the user put into the empty folder meanwhile: kept too
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="empty-2"):
        with atomic_folder(empty, marker_file="done.json") as stage:
            (stage / "done.json").write_text("run")
            (empty / "notes.txt").write_text("mine")
    assert [p.name for p in empty.iterdir()] == ["notes.txt"]
    assert _hidden(tmp_path) == []


def test_an_overwrite_that_fails_between_its_renames_puts_the_earlier_result_back(tmp_path, monkeypatch):
    final = tmp_path / "result"
    _finished(final, "done.json", "performance.mdd")
    real_replace, calls = os.replace, []

    def second_fails(src, dst):
        calls.append(dst)
        if len(calls) == 2:  # the new result into place: the name was taken meanwhile
            raise OSError(errno.ENOTEMPTY, os.strerror(errno.ENOTEMPTY), str(dst))
        return real_replace(src, dst)

    with monkeypatch.context() as patch:
        patch.setattr(atomic_module.os, "replace", second_fails)
        with pytest.raises(InputError, match="result-2"):
            with atomic_folder(final, marker_file="done.json", overwrite=True) as stage:
                (stage / "done.json").write_text("new")
    assert sorted(p.name for p in final.iterdir()) == ["done.json", "performance.mdd"]
    assert (final / "done.json").read_text() == "done.json"
    assert (tmp_path / "result-2" / "done.json").read_text() == "new"
    assert _hidden(tmp_path) == []


def test_an_empty_folder_is_written_into(tmp_path):
    final = tmp_path / "made_by_hand"
    final.mkdir()
    with atomic_folder(final, marker_file="done.json") as stage:
        (stage / "done.json").write_text("{}")
    assert [p.name for p in final.iterdir()] == ["done.json"] and _hidden(tmp_path) == []


def test_an_unwritable_destination_names_the_folder_and_the_cause(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    for target in (tmp_path / "file" / "out", tmp_path / "file" / "deeper" / "out"):
        with pytest.raises(InputError) as info:
            with atomic_folder(target, marker_file="done.json"):
                pass  # pragma: no cover
        assert info.value.path == str(target)
        assert f"{tmp_path / 'file'} is a file, not a folder" in str(info.value) and ".partial-" not in str(info.value)
    # what the system answers for /proc, a read-only mount, a folder of another user (simulated: the tests run as
    # root, whom permissions do not stop)
    for code, cause in ((errno.ENOENT, "takes no new files"), (errno.EROFS, "read-only file system"),
                        (errno.EACCES, "permission denied in")):
        def refuse(*args, code=code, **kwargs):
            raise OSError(code, os.strerror(code), os.path.join(kwargs.get("dir", ""), ".out.partial-1234"))

        with monkeypatch.context() as patch:
            patch.setattr(atomic_module.tempfile, "mkdtemp", refuse)
            with pytest.raises(InputError) as info:
                with atomic_folder(tmp_path / "out", marker_file="done.json"):
                    pass  # pragma: no cover
        message = str(info.value)
        assert message.startswith(f"{tmp_path / 'out'}: cannot create the folder: ") and cause in message
        assert ".partial-" not in message
    if os.path.isdir("/proc/self"):  # Linux: the issue's own case, unsimulated
        with pytest.raises(InputError, match="^/proc/nope: cannot create the folder: /proc takes no new files"):
            check_folder_destination("/proc/nope", marker_file="done.json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_a_single_file_that_cannot_be_written_names_the_file_and_the_cause(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="is a file, not a folder") as info:
        with atomic_path(tmp_path / "file" / "plan.json"):
            pass  # pragma: no cover
    assert info.value.path == str(tmp_path / "file" / "plan.json")
    real_open = os.open

    def read_only(path, flags, *args):
        if ".partial-" in os.fspath(path):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fspath(path))
        return real_open(path, flags, *args)

    with monkeypatch.context() as patch:
        patch.setattr(atomic_module.os, "open", read_only)
        with pytest.raises(InputError) as info:
            with atomic_path(tmp_path / "plan.json"):
                pass  # pragma: no cover
    assert str(info.value) == f"{tmp_path / 'plan.json'}: cannot write: {tmp_path} is on a read-only file system"

    # the disk fills up while the writer writes: the user's name and the cause, not the temporary name
    with pytest.raises(InputError) as info:
        with atomic_path(tmp_path / "big.npy") as tmp:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp))
    assert str(info.value) == f"{tmp_path / 'big.npy'}: cannot write: no space left in {tmp_path}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_check_file_destination(tmp_path):
    (tmp_path / "plan.json").write_text("{}")
    with pytest.raises(InputError, match="exists; pass --overwrite") as info:
        check_file_destination(tmp_path / "plan.json")
    assert info.value.path == str(tmp_path / "plan.json")
    check_file_destination(tmp_path / "plan.json", overwrite=True)
    check_file_destination(tmp_path / "new.json")
    with pytest.raises(InputError, match="does not exist"):
        check_file_destination(tmp_path / "nope" / "plan.json")
    with pytest.raises(InputError, match="is a folder"):
        check_file_destination(tmp_path, overwrite=True)
    assert [p.name for p in tmp_path.iterdir()] == ["plan.json"]


def test_recorded_paths_are_final_through_nested_staging_folders(tmp_path, monkeypatch):
    root = tmp_path.resolve()
    outside = root / "take.c3d"
    assert final_path(outside) == outside and recorded_path(outside, folder=root / "out") == str(outside)
    with atomic_folder(root / "demo", marker_file="done") as demo:
        (demo / "inputs").mkdir()
        scan = demo / "inputs" / "scan.obj"
        assert final_path(scan) == root / "demo" / "inputs" / "scan.obj"
        with atomic_folder(demo / "animation", marker_file="done") as animation:
            assert ".partial-" in str(animation.relative_to(root))
            (animation / "done").touch()
            # a file inside the folder being written: relative to it; outside: absolute, where it will be
            assert recorded_path(animation / "rig" / "rig.json", folder=animation) == "rig/rig.json"
            assert recorded_path(scan, folder=animation) == str(root / "demo" / "inputs" / "scan.obj")
            assert final_path(animation) == root / "demo" / "animation"
            assert recorded_path(outside, folder=animation) == str(outside)
        (demo / "done").touch()
        # relative input paths are recorded absolute (the working folder is not the result's)
        monkeypatch.chdir(demo)
        assert recorded_path("inputs/scan.obj", folder=demo / "animation") == str(root / "demo" / "inputs" / "scan.obj")
        monkeypatch.chdir(root)
    assert (root / "demo" / "animation" / "done").is_file()
    assert final_path(root / "demo" / "x") == root / "demo" / "x"  # nothing staged any more: unchanged
    assert resolve_recorded_path("rig/rig.json", folder=root / "a") == root / "a" / "rig" / "rig.json"
    assert resolve_recorded_path(str(outside), folder=root / "a") == outside
