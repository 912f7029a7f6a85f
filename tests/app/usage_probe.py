"""Runs many ``muble`` command lines in one process (one import instead of one per case) and prints, as JSON,
each one's exit code and stderr. Used by the usage-error tests: ``python usage_probe.py CASES.json``."""
from __future__ import annotations

import contextlib
import io
import json
import sys


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


if __name__ == "__main__":
    with open(sys.argv[1]) as f:
        cases = json.load(f)
    print(json.dumps([run_case(argv) for argv in cases]))
