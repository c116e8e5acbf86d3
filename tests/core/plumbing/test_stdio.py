"""cerberus_core.plumbing.stdio: a command prints what its streams' encoding cannot say, escaped."""
import os
import shutil
import subprocess
import sys


def test_a_path_the_terminal_cannot_encode_is_printed_escaped(pairs_dataset, tmp_path):
    """Issue 34 campaign: under PYTHONIOENCODING=ascii (or LANG=C) a non-ASCII path printed on standard output was
    a UnicodeEncodeError traceback (at the end of a finished training; here `cerberus data check`'s summary)."""
    root = tmp_path / "d\u00fc"
    shutil.copytree(pairs_dataset, root)
    env = dict(os.environ, PYTHONIOENCODING="ascii")
    done = subprocess.run([sys.executable, "-m", "cerberus_core.cli", "data", "check", "--quick", str(root)],
                          capture_output=True, env=env, timeout=120)
    out, err = done.stdout.decode("ascii"), done.stderr.decode("ascii")
    assert done.returncode == 0 and "d\\xfc" in out and out.endswith("ok\n") and "Traceback" not in err, err
