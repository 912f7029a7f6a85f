"""The results file: one evaluation run as it is shared and compared (``results.json`` beside ``report.json``).

``report.json`` is the run's full account (outcome counts, bad entries, timing, the resolved config); the results
file is the part another team needs to set a run beside theirs: what was run (protocol, track, mode, data hash,
agent, seed, versions), the summary per task type with its 95% interval, and every episode's outcome and counts, so
two runs can be paired episode by episode (``muble compare``). It carries its format name and version; a reader
refuses any other. docs/evaluation.md ("Results files") describes every field.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from muble.core.errors import ConfigError
from muble.evaluation.closed_loop import fired_kinds
from muble.evaluation.report import OVERALL
from muble.evaluation.usage import episode_usage

RESULTS_FILE = "results.json"
FORMAT = "muble-results"
VERSION = 1


def _summary_row(row: dict[str, Any]) -> dict[str, Any]:
    # The closed-loop block only for runs with disturbances: other runs' files are as they were.
    return {"episodes": row["episodes"], "successes": row["successes"], "rate": row["success_rate"],
            "ci": [row["ci_low"], row["ci_high"]], "spl": row["spl"], "measurement_ratio": row["measurement_ratio"],
            **({"closed_loop": row["closed_loop"]} if "closed_loop" in row else {})}


def _episode(record: dict[str, Any]) -> dict[str, Any]:
    # Records read back from an interrupted run of an older version may lack the measurement counts: null.
    return {"index": record["index"], "template": record["template"], "outcome": record["outcome"],
            "primitives_used": len(record["primitives"]),
            "ground_truth_primitives": record.get("ground_truth_primitives", 0),
            "measurements": record.get("measurements"),
            "ground_truth_measurements": record.get("ground_truth_measurements"),
            **({"disturbance_kinds": fired_kinds(record), "disturbances_planned": record.get("disturbances_planned", 0)}
               if "disturbances" in record else {}),
            # Tokens, cost and latencies only for an agent that counts them: other runs' files are as they were.
            **({"usage": usage} if (usage := episode_usage(record)) is not None else {})}


def results_document(*, run: dict[str, Any], manifest: dict[str, Any],
                     splits: dict[str, tuple[dict[str, Any], list[dict[str, Any]]]]) -> dict[str, Any]:
    """The results file of a run. ``run`` holds what the run followed (``protocol``, ``protocol_split``,
    ``data_sha256``, ``agent``, ``agent_config``, ``track``, ``mode``, ``seed``, ``dataset``); ``manifest`` is the
    run's manifest (versions and git revision are taken from it); ``splits`` maps each split to its summary
    (``muble.evaluation.report.summarize``) and its records in index order."""
    out: dict[str, Any] = {"format": FORMAT, "version": VERSION, **run,
                           "versions": {**manifest["versions"], "python": manifest["python"]},
                           "git": manifest["git_revision"], "splits": {}}
    for split, (summary, records) in splits.items():
        out["splits"][split] = {
            "summary": {"templates": {t: _summary_row(row) for t, row in summary["templates"].items()},
                        OVERALL: _summary_row(summary[OVERALL])},
            "episodes": [_episode(r) for r in sorted(records, key=lambda r: r["index"])],
            # Only for a run limited to the split's first episodes (evaluation.limit): others are as they were.
            **({"partial": summary["partial"]} if summary.get("partial") else {})}
    return out


def _check_episodes(path: Path, split: str, entry: Any) -> None:
    episodes = entry.get("episodes") if isinstance(entry, dict) else None
    if not isinstance(episodes, list):
        raise ConfigError(f"{path}: split '{split}' has no 'episodes' list; the file is damaged or was not written "
                          "by `muble eval`")
    for i, e in enumerate(episodes):
        if not (isinstance(e, dict) and type(e.get("index")) is int and isinstance(e.get("template"), str)
                and isinstance(e.get("outcome"), str)):
            raise ConfigError(f"{path}: episode {i} of split '{split}' needs an integer 'index' and string "
                              "'template' and 'outcome'; the file is damaged or was not written by `muble eval`")


def read_results(folder: str | Path) -> dict[str, Any]:
    """The results file of the ``muble eval`` output folder ``folder``, checked: its format and version, and every
    episode's index, template and outcome (what a comparison pairs and counts). Anything else raises
    ``ConfigError`` saying what is wrong and what to pass instead."""
    folder = Path(folder)
    path = folder / RESULTS_FILE
    if not folder.is_dir():
        raise ConfigError(f"{folder} " + ("is a file" if folder.exists() else "does not exist")
                          + "; pass the output folder of a `muble eval` run (hydra.run.dir or output.dir)")
    if not path.is_file():
        raise ConfigError(f"{folder} has no {RESULTS_FILE}; pass the output folder of a `muble eval` run (runs made "
                          f"before results files existed have none: evaluate again into a new folder)")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ConfigError(f"{path} is not valid JSON ({e}); the file is damaged: evaluate again") from e
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise ConfigError(f"{path} is not a MuBlE results file (format {found!r}, expected {FORMAT!r}); pass the "
                          "output folder of a `muble eval` run")
    if data.get("version") != VERSION:
        raise ConfigError(f"{path} is version {data.get('version')!r} of the results format; this MuBlE reads "
                          f"version {VERSION}: compare it with the MuBlE version that wrote it")
    if not isinstance(data.get("splits"), dict):
        raise ConfigError(f"{path} has no 'splits' object; the file is damaged or was not written by `muble eval`")
    for split, entry in data["splits"].items():
        _check_episodes(path, split, entry)
    return data
