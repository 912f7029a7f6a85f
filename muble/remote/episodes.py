"""What a ``reset`` may ask for, checked before anything is built, and error text fit to leave the server.

``EpisodeRequest.check`` runs on the server's request loop, so it does only cheap work: the shape of the
``episode`` document, its object count against the server's bound, the template's existence, whether the named
stored episode exists. A data episode's scene and instruction are parsed here too (pure validation, milliseconds
for the objects the bound admits), so bad data is answered at once. ``build`` does the expensive part (scene
generation, loading, plugin instances) in the simulation process.

``public_text`` strips server-side paths from any message that goes into a reply: a client learns which file
of an episode is at fault, never where the server keeps it.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from muble.core.errors import MubleError
from muble.episode.sources import EPISODE_FORMS, EpisodeFactory, EpisodeSpec, episode_kind
from muble.io.layout import DatasetLayout
from muble.remote.wire import ProtocolError

# A split the server may name: one folder name (muble.io.layout.SPLIT_NAME) without dots.
_SPLIT_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")
# An absolute path of two or more parts, not inside a word ("val/3" and "1/2" are left alone).
_ABSOLUTE_PATH = re.compile(r"(?<![\w.~-])/(?:[^\s/'\"():,;]+/)+([^\s/'\"():,;]*)")


def public_text(message: str, root: Path | None = None) -> str:
    """``message`` without server-side paths: the dataset folder becomes ``dataset.root``, any other absolute
    path its last part."""
    text = str(message)
    if root is not None:
        for form in {str(root.resolve()), str(root)}:
            if form not in ("", ".", "/"):
                text = text.replace(form, "dataset.root")
    return _ABSOLUTE_PATH.sub(lambda m: "…/" + m.group(1), text)


@dataclass
class EpisodeRequest:
    """A checked ``episode`` document: ``kind`` is ``generated``, ``stored`` or ``data``."""

    kind: str
    document: dict[str, Any]

    @classmethod
    def check(cls, episode: Any, templates: list[str], root: Path | None, max_objects: int) -> "EpisodeRequest":
        """Raise ``ProtocolError`` unless ``episode`` names an episode this server can start (``templates``: the
        registered ones)."""
        if not isinstance(episode, dict):
            raise ProtocolError("bad_request", f"'episode' must be an object: {EPISODE_FORMS}")
        kind = episode_kind(episode)
        if kind == "generated":
            index, template = episode["scene_index"], episode.get("template")
            if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < 2**31:
                raise ProtocolError("bad_request", "'scene_index' must be an integer in [0, 2**31)")
            if template is not None:
                _known_template(template, templates)
            return cls("generated", episode)
        if kind == "stored":
            _stored_exists(episode["split"], episode["index"], root)
            return cls("stored", episode)
        if kind == "data":
            _check_data(episode["scene"], episode["instruction"], templates, max_objects)
            return cls("data", episode)
        raise ProtocolError("bad_request", f"'episode' keys {sorted(map(str, episode))[:6]} name no episode; give "
                            + EPISODE_FORMS)

    def build(self, factory: EpisodeFactory, root: Path | None, max_objects: int) -> EpisodeSpec:
        """The episode's scene, instruction and task (the slow part: run it off the request loop)."""
        d = self.document
        if self.kind == "generated":
            templates = [d["template"]] if d.get("template") is not None else None
            spec = factory.generated(d["scene_index"], templates)
            if spec is None:
                raise ProtocolError("episode_error", f"no instruction of {templates or 'the template mix'} applies "
                                    f"to scene {d['scene_index']}; choose another scene_index or template")
        elif self.kind == "stored":
            spec = factory.stored(d["split"], d["index"], root)
        else:
            spec = factory.from_data(d["scene"], d["instruction"])
        if len(spec.scene.objects) > max_objects:
            raise ProtocolError("too_large", f"the scene has {len(spec.scene.objects)} objects; this server runs "
                                f"scenes of at most {max_objects} (muble serve --max-objects)")
        return spec


def _known_template(template: Any, templates: list[str]) -> str:
    if not isinstance(template, str):
        raise ProtocolError("bad_request", "'template' must be a template name (a string)")
    if template not in templates:
        raise ProtocolError("not_found", f"no template '{template[:60]}' on this server; hello lists the "
                            f"templates: {', '.join(templates)}")
    return template


def _stored_exists(split: Any, index: Any, root: Path | None) -> None:
    if not isinstance(split, str) or not _SPLIT_NAME.match(split):
        raise ProtocolError("bad_request", "'split' must be a plain name (letters, digits, '_', '-', starting with a "
                            "letter or digit), e.g. \"val\"")
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < 2**31:
        raise ProtocolError("bad_request", "'index' must be an integer in [0, 2**31)")
    if root is None or not root.is_dir():
        from muble.dataset.shipped import newest_protocol

        raise ProtocolError("not_found", "this server has no dataset of stored episodes; start it with "
                            f"`muble serve protocol={newest_protocol()} benchmark.split=mini` (a frozen benchmark's "
                            "shipped episodes) or `muble serve dataset.root=DIR` (a folder `muble data` or `muble "
                            "generate` wrote), or ask for a generated episode {scene_index, template}")
    layout = DatasetLayout(root, split)
    if not layout.split_dir.is_dir():
        splits = sorted(p.name for p in root.iterdir() if p.is_dir() and _SPLIT_NAME.match(p.name))
        raise ProtocolError("not_found", f"the server's dataset has no split '{split}'; its splits: "
                            f"{', '.join(splits) or 'none'}")
    if not (layout.split_dir / layout.scene(index)).is_file() or \
            not (layout.split_dir / layout.instruction(index)).is_file():
        raise ProtocolError("not_found", f"the server's dataset has no episode {index} in split '{split}'")


def _check_data(scene: Any, instruction: Any, templates: list[str], max_objects: int) -> None:
    from muble.io.instructions_io import instruction_from_dict
    from muble.io.scene_io import scene_from_dict

    if not isinstance(scene, dict) or not isinstance(scene.get("objects"), list):
        raise ProtocolError("bad_request", "'scene' must be a SHOP-VRB2 scene object with an 'objects' list")
    if len(scene["objects"]) > max_objects:
        raise ProtocolError("too_large", f"the scene has {len(scene['objects'])} objects; this server runs scenes "
                            f"of at most {max_objects} (muble serve --max-objects)")
    try:
        scene_from_dict(scene)
        parsed = instruction_from_dict(instruction)
    except MubleError as e:
        raise ProtocolError("episode_error", f"the episode's data is not valid SHOP-VRB2: {e}"[:600]) from None
    _known_template(parsed.template_id, templates)
