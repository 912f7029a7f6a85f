"""Runs many ``muble`` command lines in one process (one import instead of one per case) and prints, as JSON,
each one's exit code and stderr. Used by the usage-error tests: ``python usage_probe.py CASES.json``."""
from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
from pathlib import Path


def run_case(argv: list[str]) -> dict:
    from muble.app.cli import main

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else 1
        except BaseException as e:  # a traceback is what the tests look for: report it, do not die
            import traceback

            traceback.print_exc(file=err)
            code = f"raised {type(e).__name__}"
    return {"argv": argv, "code": code, "stderr": err.getvalue(), "stdout": out.getvalue()}


def run_many(cases: list[list[str]], workdir: Path) -> list[dict]:
    """Exit code, stdout and stderr of each ``muble`` command line, all run in one subprocess in ``workdir``."""
    spec = workdir / "cases.json"
    spec.write_text(json.dumps(cases))
    env = {**os.environ, "HYDRA_FULL_ERROR": "0"}
    result = subprocess.run([sys.executable, __file__, str(spec)], capture_output=True, text=True, env=env,
                            cwd=workdir, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    spec.unlink()
    return json.loads(result.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    with open(sys.argv[1]) as f:
        cases = json.load(f)
    print(json.dumps([run_case(argv) for argv in cases]))
