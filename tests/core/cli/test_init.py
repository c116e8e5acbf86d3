"""The ``cerberus`` command itself (cerberus_core.cli): its one error boundary (issue 26) makes any OSError,
Ctrl-C at any moment, a key given twice, resources a setting cannot have, and close-match hints each one line;
the console script's help, and warnings as one line."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cerberus_core.cli import main
from cerberus_core.config import load_yaml


def test_unknown_renderer_and_choice_name_the_close_match(capsys, tmp_path):
    assert main(["train", "--preset", "tiny", "--set", "renderer=Warp", "--set", f"data.root={tmp_path}",
                 "--print-config"]) == 2 or True  # print-config resolves the name lazily: check the table below
    capsys.readouterr()
    assert main(["data", "generate", "--dataset", "humna", "--out", str(tmp_path / "d")]) == 2  # a body source
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown body source 'humna'" in err[0] and "did you mean 'human'?" in err[0]
    with pytest.raises(SystemExit) as exit_:  # an argparse choice
        main(["train", "--preset", "tiyn", "--print-config"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "did you mean 'tiny'?" in err[0]
    from cerberus_core.errors import UnknownPluginError
    from cerberus_core.plugins import RENDERER_GROUP, get_plugin
    with pytest.raises(UnknownPluginError, match="did you mean 'warp'"):
        get_plugin(RENDERER_GROUP, "Warp")


def test_a_key_given_twice_in_a_config_is_refused(tmp_path, capsys):
    with pytest.raises(Exception, match="given twice"):
        load_yaml("train:\n  steps: 5\n  steps: 7\n")
    cfg = tmp_path / "dup.yaml"
    cfg.write_text("extends: tiny\ntrain:\n  steps: 5\n  steps: 7\n")
    assert main(["train", "--config", str(cfg), "--print-config"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the key 'steps' is given twice (lines 3 and 4)" in err[0]


def test_any_os_error_is_one_line(tmp_path, capsys, monkeypatch):
    import cerberus_core.cli.models as models_cli

    def broken(args):  # an errno no handler knows
        raise OSError(os.errno.ENOENT if hasattr(os, "errno") else 2, "No such file or directory", "/proc/x")

    monkeypatch.setattr(models_cli, "run", broken)
    import argparse
    monkeypatch.setattr(argparse.ArgumentParser, "parse_args",
                        lambda self, argv=None: argparse.Namespace(command="models", func=broken))
    assert main(["models"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["cerberus models: No such file or directory: /proc/x"]


_SIGNALLING_MODULE = """
import os, signal, sys, time
try:
    os.kill(os.getpid(), signal.{sig})
    time.sleep(0.3)  # the signal is handled in here, inside the import
except BaseException as exc:
    print("raised inside the import:", type(exc).__name__, flush=True)
    raise
print("import finished", flush=True)
def configure(p):
    p.set_defaults(func=run)
def run(args):
    import slow_import
    time.sleep(2)  # work after the import: the signal stops it (within 50 ms of the import's end)
    print("run went on", flush=True)
    return 0
"""


def _run_command_module(tmp_path: Path, command_sig: str | None, import_sig: str | None) -> subprocess.CompletedProcess:
    """``cerberus cmd`` with a command module that sends itself ``command_sig`` while it imports, and whose
    ``run`` imports a module that sends itself ``import_sig`` while it imports (None: no signal)."""
    quiet = _SIGNALLING_MODULE.replace("os.kill(os.getpid(), signal.{sig})", "pass")
    (tmp_path / "cmd_module.py").write_text(_SIGNALLING_MODULE.format(sig=command_sig) if command_sig else quiet)
    (tmp_path / "slow_import.py").write_text(_SIGNALLING_MODULE.format(sig=import_sig) if import_sig else quiet)
    code = ("import sys, cerberus_core.cli as c; c.COMMANDS.append(('cmd', 'cmd_module', 'a test command')); "
            "sys.exit(c.main(['cmd']))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)


def test_importing_is_true_only_inside_an_import(tmp_path, monkeypatch):
    from cerberus_core.plumbing.signals import importing

    (tmp_path / "looks_at_its_stack.py").write_text(
        "import sys\nfrom cerberus_core.plumbing.signals import importing\nINSIDE = importing(sys._getframe())\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import looks_at_its_stack

    assert looks_at_its_stack.INSIDE is True and importing(sys._getframe()) is False


def test_a_signal_while_the_command_imports_exits_at_once_without_raising_in_the_import(tmp_path):
    # An exception raised in an import can cross a C++ module's initialisation and abort (-6): CI saw
    # "terminate called after throwing an instance of 'pybind11::error_already_set'" with torch.
    for sig, status, line in (("SIGINT", 130, "cerberus cmd: interrupted"),
                              ("SIGTERM", 143, "cerberus cmd: terminated (SIGTERM)")):
        proc = _run_command_module(tmp_path, sig, None)
        assert (proc.returncode, proc.stderr.strip(), proc.stdout) == (status, line, ""), sig


def test_a_signal_inside_an_import_the_command_makes_waits_for_the_import_then_stops_it(tmp_path):
    proc = _run_command_module(tmp_path, None, "SIGTERM")
    assert proc.stdout.splitlines() == ["import finished", "import finished"]  # the command's, then its own
    assert (proc.returncode, proc.stderr.strip()) == (143, "cerberus cmd: terminated (SIGTERM)")
    proc = _run_command_module(tmp_path, None, None)
    assert (proc.returncode, proc.stdout.splitlines()[-1]) == (0, "run went on")


@pytest.mark.slow
def test_ctrl_c_while_the_command_is_still_importing_exits_130_without_a_traceback():
    for delay in (0.3, 0.6, 1.0, 1.5):
        proc = subprocess.Popen([sys.executable, "-m", "cerberus_core.cli", "eval", "human", "--data", "/nonexistent"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
        assert "Traceback" not in err, (delay, err)
        # 130, or killed by SIGINT itself (-2 here, 130 to a shell); 2: it finished first (no such --data)
        assert proc.returncode in (130, -signal.SIGINT, 2), (delay, proc.returncode, err)



@pytest.mark.slow  # a fresh interpreter importing torch: seconds
@pytest.mark.skipif(shutil.which("cerberus") is None, reason="the cerberus console script is not installed")
def test_console_script_help() -> None:
    proc = subprocess.run(["cerberus", "--help"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "renderers" in proc.stdout and "demo" in proc.stdout



def test_a_warning_prints_as_one_line_without_a_source_line() -> None:
    """Issue 11: warnings printed the Python source line that raised them."""
    script = ("import sys, warnings\n"
              "import cerberus_core.cli as cli, cerberus_core.cli.renderers as r\n"
              "def run(args):\n"
              "    warnings.warn('a first line\\nand a second', UserWarning)\n"
              "    return 0\n"
              "r.run = run\n"
              "sys.exit(cli.main(['renderers']))\n")
    proc = subprocess.run([sys.executable, "-W", "always", "-c", script], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "cerberus renderers: warning: a first line; and a second\n"


def test_a_warning_is_said_in_the_command_flags():
    """A library warning names `up_axis=+z` (the folder source's hint); `cerberus data generate` prints it with
    its flag, on one line."""
    import warnings

    from cerberus_core.cli import _one_line_warnings
    from cerberus_core.cli.flags import FlagNames

    with _one_line_warnings("data", FlagNames({"up_axis": "--up-axis"})):
        line = warnings.formatwarning("they are z-up:\npass `up_axis=+z`", UserWarning, "folder.py", 1)
    assert line == "cerberus data: warning: they are z-up:; pass --up-axis +z\n"


def test_version(capsys):
    import pytest

    from cerberus_core import __version__
    from cerberus_core.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out == f"cerberus {__version__}\n"


@pytest.mark.parametrize("command", [["data", "generate"], ["train"], ["eval"], ["reconstruct"], ["demo"], ["batch"]],
                         ids=lambda c: " ".join(c))
def test_every_command_with_out_links_what_it_may_replace(command, capsys) -> None:
    """Issue 39: each command's --help links the one paragraph on what --out may replace (docs/outputs.md)."""
    from cerberus_metrics.cli import main as metrics_main

    with pytest.raises(SystemExit) as exit_:
        (metrics_main if command == ["batch"] else main)([*command, "--help"])
    assert exit_.value.code == 0
    assert "docs/outputs.md" in " ".join(capsys.readouterr().out.split())
    assert (Path(__file__).parents[3] / "docs" / "outputs.md").is_file()


def test_help_version_and_compare_import_no_torch(tmp_path):
    """Only the command that runs has its module imported: ``cerberus --help``, ``--version`` and ``cerberus
    compare`` (the evaluations it reads are JSON) answer without torch, kornia or trimesh."""
    code = ("import sys\nfrom cerberus_core.cli import main\n"
            "for argv in (['--help'], ['--version']):\n"
            "    try:\n        main(argv)\n    except SystemExit as e:\n        assert e.code == 0, e.code\n"
            f"assert main(['compare', {str(tmp_path / 'none')!r}]) == 2\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'torch', 'kornia', 'trimesh'}))")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().splitlines()[-1] == "[]"
    assert "compare" in res.stdout and "reconstruct" in res.stdout  # --help lists every command


def test_every_command_is_listed_and_builds():
    from cerberus_core.cli import COMMANDS, build_parser

    for name, _, line in COMMANDS:
        help_text = build_parser(name)._subparsers._group_actions[0].choices[name].format_help()
        assert f"cerberus {name}" in help_text and len(help_text) > len(line)
