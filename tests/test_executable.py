"""The executable's speed trick, leaving through ``os._exit`` without the interpreter's teardown
(``bayes_imu.cli:command``, docs/architecture.md "Speed tricks"): what it guards is that every
printed line and file is out, and the status is the command's, although nothing is flushed by
the teardown it skips."""

import json
import os
import subprocess
import sys

CODE = """
import sys
from bayes_imu.cli import command
command(sys.argv[1:])
print("not reached")
"""


def _run(*args):
    # standard output is a pipe, so block-buffered (not where PYTHONUNBUFFERED is set): a line
    # left in the buffer would be lost
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    return subprocess.run([sys.executable, "-c", CODE, *args], capture_output=True, text=True,
                          timeout=120, env=env)


def test_the_executable_leaves_with_its_status_and_every_line_written(tmp_path):
    spec = tmp_path / "imu.json"
    spec.write_text(json.dumps({"kind": "gyro", "rate_hz": 100, "noise_density": 1e-3}))
    done = _run("drift", str(spec), "--horizon", "10", "--out", str(tmp_path / "o"))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[-1] == f"wrote {tmp_path / 'o' / 'drift.csv'}" and "not reached" not in done.stdout
    rows = (tmp_path / "o" / "drift.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,quantity") and rows[-1].startswith("10,attitude")
