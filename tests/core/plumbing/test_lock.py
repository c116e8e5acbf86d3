"""The folder lock (cerberus_core.plumbing.lock): one writer per folder, holder named, stale locks taken over."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import pytest

from cerberus_core.errors import LockedError
from cerberus_core.plumbing.lock import LOCK_NAME, acquire, folder_lock, read_lock


def dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_lock_records_the_holder_and_refuses_a_second_writer(tmp_path):
    with folder_lock(tmp_path / "run", "test one") as lock:
        info = read_lock(tmp_path / "run")
        assert info["pid"] == os.getpid() and info["host"] == socket.gethostname() and info["command"] == "test one"
        with pytest.raises(LockedError, match=f"in use by pid {os.getpid()} .*test one"):
            acquire(tmp_path / "run", "test two")
        assert lock.path.is_file()
    assert not (tmp_path / "run").exists(), "a folder the lock created and nothing else wrote is removed"


def test_release_keeps_a_folder_with_content_and_a_folder_that_existed(tmp_path):
    with folder_lock(tmp_path / "a"):
        (tmp_path / "a" / "x.txt").write_text("x")
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["x.txt"]
    (tmp_path / "b").mkdir()
    with folder_lock(tmp_path / "b"):
        pass
    assert (tmp_path / "b").is_dir() and list((tmp_path / "b").iterdir()) == []


def test_a_stale_lock_of_a_killed_process_is_taken_over(tmp_path, capsys):
    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": dead_pid(), "host": socket.gethostname(),
                                                  "started": 0, "command": "killed"}))
    with folder_lock(tmp_path, "new"):
        assert read_lock(tmp_path)["pid"] == os.getpid()
    assert "stale lock" in capsys.readouterr().err
    assert not (tmp_path / LOCK_NAME).exists()


def test_a_lock_held_by_another_live_process_is_refused_with_its_pid(tmp_path):
    code = ("import sys, time; from cerberus_core.plumbing.lock import acquire; acquire(sys.argv[1], 'holder'); "
            "print('held', flush=True); time.sleep(60)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE, text=True,
                            env=os.environ.copy())
    try:
        assert proc.stdout.readline().strip() == "held"
        with pytest.raises(LockedError, match=f"pid {proc.pid} "):
            acquire(tmp_path)
    finally:
        proc.kill()
        proc.wait()
    with folder_lock(tmp_path):  # killed: its lock is stale now
        assert read_lock(tmp_path)["pid"] == os.getpid()


def test_a_file_is_not_a_folder(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(LockedError, match="is a file"):
        acquire(tmp_path / "f")
