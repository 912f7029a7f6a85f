"""``muble data``: the shipped files of a frozen protocol's splits, for tools that want a folder.

    muble data protocol=shopvrb2_v2 benchmark.split=test --out data/v2     # data/v2/test/{scenes,instructions}
    muble data protocol=shopvrb2_v2 --list                                  # the splits, their sizes and hashes

The files are the split's scene and instruction files exactly as recorded (each checked against the protocol's
manifest before anything is written), in the layout ``muble generate`` writes, so ``muble eval protocol=...
dataset.root=DIR`` and any reader of SHOP-VRB2 folders take them as they are. ``--out`` gets the whole split or,
on any error, nothing.
"""
from __future__ import annotations

import argparse

from muble.core.errors import ConfigError

KEYS = {"protocol": "protocol", "benchmark.split": "split"}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="muble data", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n\n".join(__doc__.split("\n\n")[1:]))
    parser.add_argument("settings", nargs="*", metavar="KEY=VALUE",
                        help="protocol=NAME (required) and benchmark.split=SPLIT (default: mini)")
    parser.add_argument("--out", help="folder to write SPLIT/scenes and SPLIT/instructions into (created if missing)")
    parser.add_argument("--list", action="store_true", help="list the protocol's splits and which ship")
    return parser


def _settings(pairs: list[str]) -> dict[str, str]:
    out = {"split": "mini"}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or key not in KEYS:
            raise ConfigError(f"muble data takes {' and '.join(k + '=' for k in KEYS)} (and --out, --list), not "
                              f"{pair!r}")
        out[KEYS[key]] = value
    if "protocol" not in out:
        from muble.dataset.protocol import protocol_names

        raise ConfigError(f"name the protocol: protocol=NAME, one of {', '.join(protocol_names())}")
    return out


def main(argv: list[str]) -> int:
    from muble.dataset.protocol import load_protocol, shipped_archive, split_spec, write_split

    args = _parser().parse_args(argv)
    settings = _settings(args.settings)
    protocol = load_protocol(settings["protocol"])
    if args.list:
        print(f"protocol {protocol['name']} (version {protocol.get('version')})")
        for name, spec in protocol.get("splits", {}).items():
            ships = "shipped" if shipped_archive(protocol, name) is not None else "not shipped"
            print(f"  {name:18s} {spec.get('size'):>6} episodes  {ships:12s} sha256 {spec.get('sha256')}")
        return 0
    split = settings["split"]
    split_spec(protocol, split)  # an unknown split: the valid ones
    if not args.out:
        raise ConfigError("name the folder to write to: --out DIR")
    out = write_split(protocol, split, args.out)
    print(f"muble data: protocol {protocol['name']} split {split}: {split_spec(protocol, split).get('size')} "
          f"episodes in {out / split} (data sha256 {split_spec(protocol, split).get('sha256')})")
    return 0
