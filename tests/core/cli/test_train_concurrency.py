"""Two writers and interrupts: a second ``cerberus train`` into a folder in use is refused with the
holder's pid; SIGTERM / Ctrl-C checkpoint and exit 143 / 130; a stale lock of a killed run is taken over."""
from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from cerberus_core.cli import main
from cerberus_core.plumbing.lock import LOCK_NAME
from cerberus_core.train.checkpoint import load_checkpoint

pytestmark = pytest.mark.usefixtures("one_thread")  # as tests/core/train/conftest.py does


def wait_for(condition, timeout: float = 120.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > end:
            raise TimeoutError("condition not met")
        time.sleep(0.1)


def logged_steps(run: Path) -> int:
    path = run / "metrics.csv"
    return max(0, len(path.read_text().splitlines()) - 1) if path.is_file() else 0


def common(root: Path, run: Path) -> list[str]:
    return ["train", "--preset", "tiny", "--set", f"data.root={root}", "--set", "train.tensorboard=false",
            "--set", "train.progress=false", "--set", "train.image_every=0", "--set", "train.log_every=1",
            "--set", "threads=1", "--out", str(run)]


def test_second_writer_is_refused_and_sigterm_checkpoints_and_exits_143(tiny_root, tmp_path, capsys):
    run = tmp_path / "run"
    args = [*common(tiny_root, run), "--set", "train.steps=100000", "--set", "train.checkpoint_every=100000"]
    proc = subprocess.Popen([sys.executable, "-m", "cerberus_core.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    try:
        wait_for(lambda: logged_steps(run) >= 1 or proc.poll() is not None)
        assert proc.poll() is None, proc.communicate()
        before = (run / "config.yaml").read_text()
        # the reproduction: the same command with another learning rate into the same folder
        assert main([*args, "--set", "optim.lr=0.002"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"in use by pid {proc.pid} on {socket.gethostname()}" in err, err
        assert (run / "config.yaml").read_text() == before
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 143, (out, err)
    assert err.strip().splitlines()[-1] == "cerberus train: terminated (SIGTERM)"
    assert "interrupted at step" in out and "--resume" in out and "finished" not in out
    step = load_checkpoint(run / "checkpoints" / "last.pt")["step"]
    assert step >= 1 and not (run / LOCK_NAME).exists()
    assert yaml.safe_load((run / "config.yaml").read_text())["optim"]["lr"] != 0.002
    # the interrupted run continues
    assert main(["train", "--out", str(run), "--resume", "--set", f"train.steps={step + 1}",
                 "--set", "train.progress=false"]) == 0
    assert f"finished step {step + 1}" in capsys.readouterr().out


def test_ctrl_c_checkpoints_and_exits_130_and_a_stale_lock_is_taken_over(tiny_root, tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (run / LOCK_NAME).write_text(json.dumps({"pid": dead.pid, "host": socket.gethostname(), "started": 0,
                                             "command": "cerberus train (killed)"}))

    def interrupt() -> None:
        wait_for(lambda: logged_steps(run) >= 1)
        os.kill(os.getpid(), signal.SIGINT)

    thread = threading.Thread(target=interrupt, daemon=True)
    thread.start()
    code = main([*common(tiny_root, run), "--set", "train.steps=100000", "--set", "train.checkpoint_every=100000"])
    thread.join()
    out, err = capsys.readouterr()
    assert code == 130, (out, err)
    assert "stale lock" in err and err.strip().splitlines()[-1] == "cerberus train: interrupted"
    assert "interrupted at step" in out
    assert load_checkpoint(run / "checkpoints" / "last.pt")["step"] >= 1
    assert not (run / LOCK_NAME).exists()
