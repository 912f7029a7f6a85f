"""An agent in its own process driving ``muble serve`` episodes: ``muble eval``'s episodes, over the protocol.

    muble serve protocol=shopvrb2_v2 benchmark.split=mini &        # the frozen benchmark (127.0.0.1:5555)
    python docs/examples/remote_agent.py --split mini --indices 0-19  # its shipped episodes, as muble eval
    muble serve dataset.root=/data/shopvrb2 &                      # or a dataset folder
    python docs/examples/remote_agent.py --split val --indices 0-19   # stored dataset episodes, as muble eval
    python docs/examples/remote_agent.py --generated 0-9 --template stack_simple   # generated scenes

Writes one JSON record per episode (outcome, primitives, answer, error) to stdout and a success table per
template at the end. The agent here is the built-in oracle (``--agent random`` for the baseline); replace it with
anything that implements ``muble.Agent`` — or speak the protocol directly from another language (docs/remote.md).
"""
from __future__ import annotations

import argparse
import collections
import json

from muble import PluginError, get_registry
from muble.remote import RemoteClient, RemoteError, run_agent


def indices(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--address", default="tcp://127.0.0.1:5555")
    p.add_argument("--agent", default="oracle")
    p.add_argument("--split", default="val")
    p.add_argument("--indices", type=indices, help="stored dataset indices of --split, e.g. 0-19")
    p.add_argument("--generated", type=indices, help="generated scene indices instead, e.g. 0-9")
    p.add_argument("--template", help="with --generated: the template (default: the server's mix)")
    args = p.parse_args()
    if args.generated is not None:
        episodes = [{"scene_index": i, **({"template": args.template} if args.template else {})}
                    for i in args.generated]
    else:
        episodes = [{"split": args.split, "index": i} for i in (args.indices or [0])]
    try:
        agent = get_registry().create("agent", args.agent, {})
    except PluginError as e:  # a mistyped --agent: the valid names and the closest, exit 2, no traceback
        p.error(f"--agent: {e}")
    table: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
    with RemoteClient(args.address) as client:
        try:
            hello = client.hello()
        except RemoteError as e:  # no server there: say how to start one, exit 2, no traceback
            p.error(f"{e}; start the server first (`muble serve protocol=shopvrb2_v2` or `muble serve "
                    "dataset.root=DIR`) or point --address at it")
        print(f"# server speaks {hello['protocol']}")
        for episode in episodes:
            try:
                record = run_agent(agent, client, episode)
            except RemoteError as e:  # bad data or an episode that cannot start: recorded, the run goes on
                record = {"episode": episode, "template": "unknown", "outcome": "invalid_data", "error": str(e)}
            print(json.dumps(record))
            table[record["template"]][record["outcome"] == "success"] += 1
    for template, counts in sorted(table.items()):
        total = counts[True] + counts[False]
        print(f"# {template:24s} {counts[True]}/{total} success")


if __name__ == "__main__":
    main()
