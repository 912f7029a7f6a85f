"""Freeze a protocol split: record its data manifest and hash, and pack its files to ship with MuBlE.

    python scripts/freeze_protocol.py shopvrb2_v2 mini DIR     # DIR: the dataset.root `muble generate` wrote

Writes ``muble_conf/protocol/<name>.<split>.json`` (the manifest), ``<name>.<split>.tar.xz`` (the scene and
instruction files) and the split's ``sha256`` in ``<name>.yaml``; refuses a split whose files are incomplete.
Frozen splits are not frozen again: the script refuses a split whose recorded hash is another one.
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

from muble.dataset.protocol import ARCHIVE, data_manifest, load_protocol, manifest_hash, pack_split

CONF = Path(__file__).resolve().parents[1] / "muble_conf" / "protocol"


def main(name: str, split: str, root: str) -> None:
    protocol = load_protocol(name)
    spec = protocol["splits"][split]
    files = data_manifest(root, split)
    if len(files) != 2 * spec["size"]:
        sys.exit(f"{root}/{split} holds {len(files)} scene and instruction files, not {2 * spec['size']}")
    digest = manifest_hash(files)
    if spec.get("sha256") not in (None, digest):
        sys.exit(f"{name} {split} is frozen with hash {spec['sha256']}; {root} has {digest}")
    pack_split(root, split, CONF / ARCHIVE.format(name=name, split=split))
    (CONF / f"{name}.{split}.json").write_text(json.dumps(
        {"protocol": name, "split": split, "sha256": digest, "files": files}, indent=1, sort_keys=True) + "\n")
    config = CONF / f"{name}.yaml"
    text = config.read_text()
    # The split's own line (``mini: {size: 100, sha256: null, ...}``) or block (``sha256: null`` under it).
    inline = re.compile(rf"(\n    {split}: {{size: \d+, sha256: )(null|[0-9a-f]{{64}})")
    block = re.compile(rf"(\n    {split}:\n      size: \d+\n      sha256: )(null|[0-9a-f]{{64}})")
    text, n = inline.subn(rf"\g<1>{digest}", text)
    if not n:
        text, n = block.subn(rf"\g<1>{digest}", text)
    if n != 1:
        sys.exit(f"split {split} not found in {config}")
    config.write_text(text)
    print(f"{name} {split}: {len(files)} files, sha256 {digest}")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
