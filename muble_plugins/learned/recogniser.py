"""The attribute recogniser: an object's crop to its name, colour, material, shape and size (NS-AP's ResNet).

It learns from the files of a dataset written by ``muble generate``: each complete scene index (its instruction
file written) has a scene file, whose objects carry their attribute words and a COCO-RLE mask of the scene's
image, and that image. Each visible object becomes one *crop*: the image cut to the square around the mask's
bounding box (10 % margin, zero padding past the border), resized to ``crop_size``, with the mask as a fourth
channel, so the network knows which of two overlapping objects is meant. A crop loses the object's size in the
image, which ``size`` (scale 0.85, 1 or 1.15 of a model) depends on, so eight numbers go beside it: the mask's
bounding box in image fractions (left, top, right, bottom), the square root of its area fraction, and the
object's bounding-box extents in metres (x, y, z of its own frame), which the scene file holds and ``masks``
mode shows every agent (docs/protocol.md). Everything is read through ``muble.core`` (scene files, the
dataset's layout), and the crops of the training data and of an episode's observation are cut by the same
function.

The network is torchvision's ResNet-18 (random initialisation, a four-channel first convolution, no classifier)
with a small layer for the geometry and one linear head per attribute. Affordances (stackable, stack base,
pickupable) are not learned: they are looked up from the predicted name, as the training data pairs them (the
most frequent triple of each name). ``size`` is a model's scale (0.85, 1, 1.15), which a crop shows only as a
few per cent of the mask's size and the network's head learns poorly (about half right); the training data's
(name, extents) -> size pairs make a nearest-neighbour table, which gives the size from the predicted name and
the object's extents (``size_table`` in the checkpoint; the head's word where a checkpoint has none).

``data_root`` is either one dataset (a folder with ``dataset_config.json``) or a folder whose sub-folders (or
links) are datasets, e.g. one rendered with MuJoCo and one with Blender; ``renderers`` picks which ones count by
the renderer their ``dataset_config.json`` names. Scenes, not crops, are held out for validation: a scene's key is
its generator seed and index, so the same scene drawn by two renderers falls on the same side.
"""
from __future__ import annotations

import hashlib
import json
import math
import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from muble import Trainer
from muble.core import streams
from muble.core.errors import ConfigError
from muble.core.ranges import configured
from muble.core.training import TrainingRun
from muble.io.layout import DatasetLayout
from muble.io.scene_io import load_scene

from muble_plugins.learned import checkpoint as ck
from muble_plugins.learned.config import RecogniserTrainerConfig

log = logging.getLogger(__name__)

KIND = "recogniser"
ATTRIBUTES = ("name", "colour", "material", "shape", "size")
AFFORDANCES = ("stackable", "stack_base", "pickupable")
GEOMETRY = 8  # left, top, right, bottom (fractions of the image), sqrt(area fraction), extents x, y, z (m)
EXTENT_SCALE = 5.0  # metres to the network's input scale (objects are 0.05-0.4 m)
MARGIN = 0.1  # of the bounding box's longer side, on each side
MIN_PIXELS = 4  # fewer visible pixels: no crop
# The training's streams (muble.core.streams), keyed by the run's seed.
HOLD_OUT_STREAM = streams.declare("train.recogniser.hold_out", "the scenes held out for validation")
ORDER_STREAM = streams.declare("train.recogniser.order", "the order of the training crops in an epoch (epoch)")
FLIP_STREAM = streams.declare("train.recogniser.flips", "which training crops an epoch mirrors (epoch)")


# -- crops ------------------------------------------------------------------------------------------------------
def decode_mask(rle: Any, shape: tuple[int, int] | None = None) -> np.ndarray:
    """A COCO RLE (``muble.core.scene.RLE`` or its dict) as a boolean (H, W) mask, resized (nearest) to ``shape``
    when given and different (a mask of another resolution than the image)."""
    from pycocotools import mask as coco

    if hasattr(rle, "to_dict"):
        rle = rle.to_dict()
    counts = rle["counts"]
    mask = coco.decode({"size": list(rle["size"]), "counts": counts.encode() if isinstance(counts, str) else counts})
    mask = mask.astype(bool)
    if shape is not None and mask.shape != tuple(shape):
        from PIL import Image

        mask = np.asarray(Image.fromarray(mask.astype(np.uint8) * 255).resize((shape[1], shape[0]),
                                                                              Image.NEAREST)) > 127
    return mask


def object_crop(rgb: np.ndarray, mask: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(crop (4, size, size) uint8: RGB and the mask, geometry (5,) float32) of one object, or None when fewer
    than ``MIN_PIXELS`` of it are visible."""
    from PIL import Image

    ys, xs = np.nonzero(mask)
    if len(ys) < MIN_PIXELS:
        return None
    height, width = mask.shape
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    side = int(np.ceil(max(y1 - y0, x1 - x0) * (1 + 2 * MARGIN))) + 2
    top, left = (y0 + y1 - side) // 2, (x0 + x1 - side) // 2
    canvas = np.zeros((side, side, 4), np.uint8)
    sy0, sy1, sx0, sx1 = max(top, 0), min(top + side, height), max(left, 0), min(left + side, width)
    canvas[sy0 - top:sy1 - top, sx0 - left:sx1 - left, :3] = rgb[sy0:sy1, sx0:sx1, :3]
    canvas[sy0 - top:sy1 - top, sx0 - left:sx1 - left, 3] = mask[sy0:sy1, sx0:sx1] * 255
    rgb_small = np.asarray(Image.fromarray(canvas[..., :3]).resize((size, size), Image.BILINEAR))
    mask_small = np.asarray(Image.fromarray(canvas[..., 3]).resize((size, size), Image.BILINEAR))
    crop = np.concatenate([rgb_small, mask_small[..., None]], axis=2).transpose(2, 0, 1)
    geometry = np.array([x0 / width, y0 / height, x1 / width, y1 / height,
                         np.sqrt(len(ys) / (height * width))], np.float32)
    return np.ascontiguousarray(crop), geometry


def object_extents(obj: Any) -> np.ndarray:
    """The object's bounding-box extents (x, y, z, metres) from its ``bbox`` ({x, y, z} extents, or eight corners),
    zeros when it has none."""
    box = getattr(obj, "bbox", None)
    try:
        if isinstance(box, dict):
            return np.array([float(box["x"]), float(box["y"]), float(box["z"])], np.float32)
        if box is not None and len(box) == 8:
            corners = np.asarray(box, np.float32)
            return (corners.max(0) - corners.min(0)).astype(np.float32)
    except (KeyError, TypeError, ValueError):
        pass
    return np.zeros(3, np.float32)


def object_features(rgb: np.ndarray, mask: np.ndarray, obj: Any, size: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(crop, geometry (8,)) of one object: ``object_crop`` with the object's extents; None when not visible."""
    cut = object_crop(rgb, mask, size)
    if cut is None:
        return None
    return cut[0], np.concatenate([cut[1], object_extents(obj)]).astype(np.float32)


@dataclass
class Crops:
    """Object crops with their labels: ``images`` (N, 4, S, S) uint8, ``geometry`` (N, 8) float32, ``labels``
    attribute -> N words, ``affordances`` N triples, ``scene`` N scene keys, ``renderer`` N renderer names."""

    images: np.ndarray
    geometry: np.ndarray
    labels: dict[str, list[str]]
    affordances: list[tuple[bool, bool, bool]]
    scene: list[str]
    renderer: list[str]
    scenes_read: int = 0

    def __len__(self) -> int:
        return len(self.images)

    def subset(self, keep: Iterable[int]) -> "Crops":
        idx = np.asarray(list(keep), dtype=np.int64)
        pick = lambda items: [items[i] for i in idx]  # noqa: E731
        return Crops(self.images[idx], self.geometry[idx], {a: pick(v) for a, v in self.labels.items()},
                     pick(self.affordances), pick(self.scene), pick(self.renderer),
                     len(set(pick(self.scene))))


def dataset_folders(root: str | Path) -> list[tuple[Path, str]]:
    """(dataset root, renderer name) of ``root`` itself, or of each folder in it, that ``muble generate`` wrote
    (holds ``dataset_config.json``); ``ConfigError`` when there is none."""
    root = Path(root)
    if not root.is_dir():
        raise ConfigError(f"recogniser data: '{root}' is not a folder; give train.data_root=DIR, the root of a "
                          "dataset written by `muble generate` (or a folder of such datasets)")
    candidates = [root] if (root / "dataset_config.json").is_file() else sorted(
        p for p in root.iterdir() if p.is_dir() and (p / "dataset_config.json").is_file())
    found = []
    for folder in candidates:
        try:
            config = json.loads((folder / "dataset_config.json").read_text())
            renderer = str((config.get("renderer") or {}).get("name") or "none")
        except (OSError, ValueError, AttributeError) as e:
            raise ConfigError(f"recogniser data: '{folder / 'dataset_config.json'}' is not readable ({e})") from e
        found.append((folder, renderer))
    if not found:
        raise ConfigError(f"recogniser data: '{root}' holds no dataset (no dataset_config.json in it or in its "
                          "sub-folders); write one with `muble generate dataset.root=DIR` (dataset.sequences=false "
                          "is enough) and give train.data_root=DIR")
    return found


def _splits(folder: Path) -> list[str]:
    try:
        splits = json.loads((folder / "dataset_splits.json").read_text()).get("splits") or {}
        return sorted(splits)
    except (OSError, ValueError, AttributeError):
        return sorted(p.name for p in folder.iterdir() if (p / "scenes").is_dir())


def scene_entries(root: str | Path, renderers: list[str] | None = None) -> list[tuple[str, str, Path, Path]]:
    """(scene key, renderer, scene file, image file) of every complete scene index of the datasets under
    ``root`` (its instruction file written, its image present), ordered by key then renderer."""
    entries = []
    folders = dataset_folders(root)
    chosen = [(f, r) for f, r in folders if renderers is None or r in renderers]
    if not chosen:
        raise ConfigError(f"recogniser data: no dataset under '{root}' was rendered with "
                          f"{', '.join(renderers or [])}; found: {', '.join(f'{f.name} ({r})' for f, r in folders)}")
    for folder, renderer in chosen:
        config = json.loads((folder / "dataset_config.json").read_text())
        seed = config.get("seed")
        for split in _splits(folder):
            layout = DatasetLayout(folder, split)
            for scene_path in sorted((layout.split_dir / "scenes").glob("*.json")):
                stem = scene_path.stem
                image = layout.split_dir / "images" / f"{stem}.png"
                if not (layout.split_dir / "instructions" / f"{stem}.json").is_file() or not image.is_file():
                    continue
                entries.append((f"{seed}/{split}/{stem.rsplit('_', 1)[-1]}", renderer, scene_path, image))
    return sorted(entries, key=lambda e: (e[0], e[1]))


def read_crops(entries: list[tuple[str, str, Path, Path]], crop_size: int, progress=None) -> Crops:
    """The crops of every visible object of these scenes (``scene_entries``)."""
    from PIL import Image

    images, geometry, affordances, scenes, renderers = [], [], [], [], []
    labels: dict[str, list[str]] = {a: [] for a in ATTRIBUTES}
    items = entries if progress is None else progress(entries)
    for key, renderer, scene_path, image_path in items:
        scene = load_scene(scene_path)
        rgb = np.asarray(Image.open(image_path).convert("RGB"))
        for obj in scene.objects:
            if obj.mask is None:
                continue
            cut = object_features(rgb, decode_mask(obj.mask, rgb.shape[:2]), obj, crop_size)
            if cut is None:
                continue
            images.append(cut[0])
            geometry.append(cut[1])
            for a in ATTRIBUTES:
                labels[a].append(str(getattr(obj, a)))
            affordances.append((bool(obj.stackable), bool(obj.stack_base), bool(obj.pickupable)))
            scenes.append(key)
            renderers.append(renderer)
    if not images:
        return Crops(np.zeros((0, 4, crop_size, crop_size), np.uint8), np.zeros((0, GEOMETRY), np.float32),
                     labels, [], [], [], 0)
    return Crops(np.stack(images), np.stack(geometry), labels, affordances, scenes, renderers,
                 len({e[0] for e in entries}))


def load_dataset_crops(root: str | Path, crop_size: int, renderers: list[str] | None = None,
                       scenes: int | None = None) -> Crops:
    """The crops of the first ``scenes`` scene keys (all when None) of the datasets under ``root``."""
    entries = scene_entries(root, renderers)
    if scenes is not None:
        keys = sorted({e[0] for e in entries}, key=_key_order)[:scenes]
        keep = set(keys)
        entries = [e for e in entries if e[0] in keep]
    return read_crops(entries, crop_size)


def _key_order(key: str) -> tuple:
    seed, split, index = key.split("/")
    return (seed, split, int(index) if index.isdigit() else index)


# -- the network ------------------------------------------------------------------------------------------------
def build_network(sizes: dict[str, int]):
    """ResNet-18 (random initialisation) on four channels, plus the geometry, with one head per attribute."""
    import torch
    import torchvision
    from torch import nn

    class RecogniserNet(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            backbone = torchvision.models.resnet18(weights=None)
            backbone.conv1 = nn.Conv2d(4, 64, kernel_size=7, stride=2, padding=3, bias=False)
            backbone.fc = nn.Identity()
            self.backbone = backbone
            self.geometry = nn.Sequential(nn.Linear(GEOMETRY, 32), nn.ReLU())
            self.heads = nn.ModuleDict({a: nn.Linear(512 + 32, n) for a, n in sizes.items()})

        def forward(self, images, geometry):
            x = images.float() / 127.5 - 1.0
            g = torch.cat([geometry[:, :5] * 4.0 - 2.0, geometry[:, 5:] * EXTENT_SCALE], dim=1)
            features = torch.cat([self.backbone(x), self.geometry(g)], dim=1)
            return {a: head(features) for a, head in self.heads.items()}

    return RecogniserNet()


def _logits(net, images: np.ndarray, geometry: np.ndarray, batch: int = 256) -> dict[str, np.ndarray]:
    import torch

    out: dict[str, list[np.ndarray]] = {}
    with torch.no_grad():
        for start in range(0, len(images), batch):
            found = net(torch.from_numpy(images[start:start + batch]),
                        torch.from_numpy(geometry[start:start + batch]))
            for a, v in found.items():
                out.setdefault(a, []).append(v.numpy())
    return {a: np.concatenate(v) for a, v in out.items()}


def accuracy(predicted: dict[str, list[str]], crops: Crops) -> dict[str, float]:
    """Share of crops whose word is right, per attribute (and ``all``: every attribute right)."""
    n = len(crops)
    if n == 0:
        return {a: float("nan") for a in ATTRIBUTES + ("all",)}
    right = {a: np.array([p == t for p, t in zip(predicted[a], crops.labels[a])]) for a in ATTRIBUTES}
    out = {a: float(v.mean()) for a, v in right.items()}
    out["all"] = float(np.logical_and.reduce([right[a] for a in ATTRIBUTES]).mean())
    return out


# -- training ---------------------------------------------------------------------------------------------------
def _vocabularies(crops: Crops) -> dict[str, list[str]]:
    return {a: sorted(set(crops.labels[a])) for a in ATTRIBUTES}


def _affordance_table(crops: Crops) -> dict[str, dict[str, bool]]:
    """Per name, the affordance triple the data pairs it with most often."""
    from collections import Counter

    counts: dict[str, Counter] = {}
    for name, triple in zip(crops.labels["name"], crops.affordances):
        counts.setdefault(name, Counter())[triple] += 1
    return {name: dict(zip(AFFORDANCES, c.most_common(1)[0][0])) for name, c in sorted(counts.items())}


def _size_table(crops: Crops) -> list[list]:
    """[name, [x, y, z], size] of every (name, extents to the millimetre) of the crops, its most frequent size."""
    from collections import Counter

    counts: dict[tuple, Counter] = {}
    for name, extents, size in zip(crops.labels["name"], crops.geometry[:, 5:8], crops.labels["size"]):
        counts.setdefault((name, tuple(np.round(extents, 3).tolist())), Counter())[size] += 1
    return [[name, list(extents), c.most_common(1)[0][0]] for (name, extents), c in sorted(counts.items())]


def sizes_from_table(names: list[str], geometry: np.ndarray, table: list[list]) -> list[str | None]:
    """Per crop, the size of the nearest (by extents) table entry of its name; None where the name has none."""
    by_name: dict[str, tuple[np.ndarray, list[str]]] = {}
    for name, extents, size in table:
        points, words = by_name.setdefault(name, (np.zeros((0, 3), np.float32), []))
        by_name[name] = (np.vstack([points, np.asarray(extents, np.float32)[None]]), words + [size])
    out: list[str | None] = []
    for name, extents in zip(names, np.asarray(geometry, np.float32)[:, 5:8]):
        if name not in by_name or not extents.any():
            out.append(None)
            continue
        points, words = by_name[name]
        out.append(words[int(np.argmin(((points - extents) ** 2).sum(1)))])
    return out


def _indices(crops: Crops, vocabularies: dict[str, list[str]]) -> dict[str, np.ndarray]:
    out = {}
    for a in ATTRIBUTES:
        lookup = {w: i for i, w in enumerate(vocabularies[a])}
        out[a] = np.array([lookup.get(w, -100) for w in crops.labels[a]], np.int64)  # -100: ignored by the loss
    return out


def _hold_out(keys: list[str], fraction: float, seed: int) -> set[str]:
    unique = sorted(set(keys), key=_key_order)
    count = int(round(fraction * len(unique)))
    if fraction > 0 and len(unique) > 1:
        count = min(max(count, 1), len(unique) - 1)
    order = streams.stream(HOLD_OUT_STREAM, seed).permutation(len(unique))
    return {unique[i] for i in order[:count]}


SCHEDULES = ("cosine", "constant")


def learning_rate_schedule(torch: Any, optimiser: Any, kind: str, crops: int, batch_size: int, epochs: int):
    """The recogniser's learning-rate schedule, stepped once per batch: ``cosine`` (a linear warm-up over the first
    tenth of the steps, at most 200, then cosine decay to zero at the last step) or ``constant``."""
    if kind not in SCHEDULES:
        raise ConfigError(f"trainer.schedule must be one of {', '.join(SCHEDULES)}, got '{kind}'")
    if kind == "constant":
        return torch.optim.lr_scheduler.LambdaLR(optimiser, lambda step: 1.0)
    # Batches of fewer than two crops are skipped (batch norm), so this may count one step more than are taken.
    total = max(1, math.ceil(crops / batch_size) * epochs)
    warmup = min(200, max(1, total // 10))
    return torch.optim.lr_scheduler.LambdaLR(optimiser, lambda step: min(
        (step + 1) / warmup, 0.5 * (1 + math.cos(math.pi * min(1.0, step / total)))))


class RecogniserTrainer(Trainer):
    """``muble train trainer=recogniser train.data_root=DIR``: ResNet-18 on object crops of a generated dataset."""

    def __init__(self, config: RecogniserTrainerConfig | None = None, **options: Any) -> None:
        self.config = configured(RecogniserTrainerConfig, config, options, owner="trainer 'recogniser'")
        if self.config.schedule not in SCHEDULES:
            raise ConfigError(f"trainer.schedule must be one of {', '.join(SCHEDULES)}, got '{self.config.schedule}'")

    def settings(self) -> dict[str, Any]:
        settings = asdict(self.config)
        if settings["renderers"] is not None:
            settings["renderers"] = sorted(str(r) for r in settings["renderers"])
        return settings

    def train(self, run: TrainingRun) -> dict[str, Any]:
        torch = ck.torch_module()
        cfg = self.config
        if run.data_root is None:
            raise ConfigError("the recogniser learns from a generated dataset's images: give train.data_root=DIR "
                              "(written by `muble generate dataset.root=DIR`, dataset.sequences=false is enough)")
        ck.set_threads(run)
        ck.seed_everything(run.seed)
        began = time.perf_counter()
        entries = scene_entries(run.data_root, cfg.renderers)
        keys = sorted({e[0] for e in entries}, key=_key_order)[:cfg.scenes]
        chosen = set(keys)
        entries = [e for e in entries if e[0] in chosen]
        crops = read_crops(entries, cfg.crop_size, lambda items: ck.progress(items, run, "crops", len(entries)))
        if len(crops) == 0:
            raise ConfigError(f"recogniser data: no object crops under '{run.data_root}' (no complete scene with "
                              "an image and object masks)")
        held = _hold_out(crops.scene, cfg.validation_fraction, run.seed)
        train = crops.subset(i for i, k in enumerate(crops.scene) if k not in held)
        val = crops.subset(i for i, k in enumerate(crops.scene) if k in held)
        data_seconds = time.perf_counter() - began
        vocabularies = _vocabularies(train)
        affordances = _affordance_table(train)
        size_table = _size_table(train)
        targets = _indices(train, vocabularies)

        net = build_network({a: len(v) for a, v in vocabularies.items()})
        optimiser = torch.optim.Adam(net.parameters(), lr=cfg.learning_rate)
        schedule = learning_rate_schedule(torch, optimiser, cfg.schedule, len(train), cfg.batch_size, cfg.epochs)
        path = run.out_dir / f"{KIND}.pt"
        ident = ck.identity(run, self.settings())
        # What the data root held: a resumed run over a dataset that has grown since would train on other crops.
        ident["data"] = hashlib.sha256(json.dumps([[e[0], e[1]] for e in entries]).encode()).hexdigest()
        start_epoch, history = 0, []
        previous = ck.resume_from(path, KIND, run, ident)
        if previous is not None:
            start_epoch = ck.restore(previous, net, optimiser, schedule)
            history = list(previous["extra"].get("history", []))
            log.info("recogniser: resuming after epoch %d of %d", start_epoch, cfg.epochs)

        images = torch.from_numpy(train.images)
        geometry = torch.from_numpy(train.geometry)
        labels = {a: torch.from_numpy(v) for a, v in targets.items()}
        train_seconds = float(previous["extra"].get("train_seconds", 0.0)) if previous else 0.0
        extra: dict[str, Any] = {}
        for epoch in range(start_epoch, cfg.epochs):
            epoch_began = time.perf_counter()
            net.train()
            # The order of an epoch depends only on (seed, epoch), so a resumed run draws the same batches.
            order = torch.randperm(len(train), generator=torch.Generator().manual_seed(
                streams.integer_seed(ORDER_STREAM, run.seed, epoch)))
            flips = torch.rand(len(train), generator=torch.Generator().manual_seed(
                streams.integer_seed(FLIP_STREAM, run.seed, epoch))) < 0.5
            total, batches = 0.0, 0
            steps = range(0, len(train), cfg.batch_size)
            for start in ck.progress(steps, run, f"epoch {epoch + 1}/{cfg.epochs}", len(steps)):
                idx = order[start:start + cfg.batch_size]
                if len(idx) < 2:  # batch norm needs two crops; the one left over waits for the next epoch
                    continue
                x, g = images[idx], geometry[idx].clone()
                flip = flips[idx]
                if flip.any():  # a mirrored object is the same object: its box mirrors too
                    x = x.clone()
                    x[flip] = x[flip].flip(-1)
                    g[flip, 0], g[flip, 2] = 1 - geometry[idx][flip, 2], 1 - geometry[idx][flip, 0]
                out = net(x, g)
                loss = sum(torch.nn.functional.cross_entropy(out[a], labels[a][idx], ignore_index=-100)
                           for a in ATTRIBUTES)
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                schedule.step()
                total += float(loss.detach())
                batches += 1
            train_seconds += time.perf_counter() - epoch_began
            net.eval()
            val_acc = accuracy(predict_words(net, vocabularies, val.images, val.geometry, size_table), val)
            history.append({"epoch": epoch + 1, "loss": total / max(batches, 1),
                            **{f"val_{a}": v for a, v in val_acc.items()}})
            log.info("recogniser epoch %d: loss %.3f, validation %s", epoch + 1, total / max(batches, 1),
                     ", ".join(f"{a} {v:.3f}" for a, v in val_acc.items()))
            extra = {"vocabularies": vocabularies, "affordances": affordances, "size_table": size_table,
                     "crop_size": cfg.crop_size,
                     "geometry": GEOMETRY, "history": history, "train_seconds": train_seconds,
                     "data": {"scenes": len(keys), "train_scenes": train.scenes_read,
                              "validation_scenes": val.scenes_read, "train_crops": len(train),
                              "validation_crops": len(val), "renderers": sorted(set(crops.renderer))}}
            ck.save(path, KIND, run, ident, epoch + 1,
                    {"model": net.state_dict(), "optimiser": optimiser.state_dict(),
                     "schedule": schedule.state_dict(), "rng": ck.rng_states()}, extra)
        last = history[-1] if history else {}
        figures: dict[str, Any] = {
            "data_seconds": data_seconds, "train_seconds": train_seconds, "scenes": len(keys),
            "train_crops": len(train), "validation_scenes": val.scenes_read, "validation_crops": len(val),
            "renderers": ",".join(sorted(set(crops.renderer))), "epochs": len(history)}
        for a in ATTRIBUTES + ("all",):
            figures[f"val_accuracy_{a}"] = last.get(f"val_{a}", float("nan"))
        figures["checkpoint"] = str(path)
        return figures


def predict_words(net, vocabularies: dict[str, list[str]], images: np.ndarray, geometry: np.ndarray,
                  size_table: list[list] | None = None) -> dict[str, list[str]]:
    """Words per attribute: each head's best word; ``size`` from ``size_table`` (``sizes_from_table``) where it
    has the predicted name."""
    if len(images) == 0:
        return {a: [] for a in vocabularies}
    logits = _logits(net, images, geometry)
    words = {a: [vocabularies[a][i] for i in logits[a].argmax(1)] for a in vocabularies}
    if size_table:
        looked_up = sizes_from_table(words["name"], geometry, size_table)
        words["size"] = [t if t is not None else w for t, w in zip(looked_up, words["size"])]
    return words


# -- using a trained recogniser ---------------------------------------------------------------------------------
@dataclass
class AttributeRecogniser:
    """A trained recogniser (``AttributeRecogniser.load(path)``): ``predict`` on crops, ``recognise`` on a
    masks-mode observation."""

    net: Any
    vocabularies: dict[str, list[str]]
    affordances: dict[str, dict[str, bool]]
    crop_size: int
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def load(cls, path: str | Path) -> "AttributeRecogniser":
        payload = ck.load(path, KIND)
        extra = payload.get("extra") or {}
        try:
            vocabularies, crop_size = extra["vocabularies"], int(extra["crop_size"])
            net = build_network({a: len(vocabularies[a]) for a in ATTRIBUTES})
            net.load_state_dict(payload["state"]["model"])
        except (KeyError, TypeError, RuntimeError) as e:
            raise ConfigError(f"'{path}' does not hold this recogniser's network ({e}); train it again with "
                              "`muble train trainer=recogniser`") from e
        net.eval()
        return cls(net, vocabularies, extra.get("affordances") or {}, crop_size, extra)

    def predict(self, crops: np.ndarray | Crops, geometry: np.ndarray | None = None) -> dict[str, list[str]]:
        """Words per attribute for crops (``Crops``, or (N, 4, S, S) uint8 images with their (N, 8) geometry,
        ``object_features``)."""
        if isinstance(crops, Crops):
            crops, geometry = crops.images, crops.geometry
        if geometry is None:
            raise ValueError("predict needs each crop's geometry (object_features returns it)")
        if len(crops) and crops.shape[-1] != self.crop_size:
            raise ValueError(f"crops of {crops.shape[-1]} pixels given; this recogniser was trained on "
                             f"{self.crop_size}")
        return predict_words(self.net, self.vocabularies, np.asarray(crops, np.uint8),
                             np.asarray(geometry, np.float32), self.extra.get("size_table"))

    def recognise(self, observation: Any) -> dict[int, dict[str, Any]]:
        """Per visible object id of a masks-mode observation: its name, colour, material, shape and size, and
        the affordances of that name (stackable, stack_base, pickupable). The masks are those of the first
        camera's latest image; an object with no visible pixel is left out (ask again after another image)."""
        if not observation.images:
            raise ValueError("recognise needs the observation's images (masks mode)")
        frame = next(iter(observation.images.values()))
        rgb = np.asarray(frame.rgb)
        ids, images, geometry = [], [], []
        for obj in observation.scene.objects:
            if obj.mask is not None:
                mask = decode_mask(obj.mask, rgb.shape[:2])
            elif frame.segmentation is not None:
                mask = np.asarray(frame.segmentation) == obj.id
            else:
                continue
            cut = object_features(rgb, mask, obj, self.crop_size)
            if cut is None:
                continue
            ids.append(int(obj.id))
            images.append(cut[0])
            geometry.append(cut[1])
        if not ids:
            return {}
        words = self.predict(np.stack(images), np.stack(geometry))
        out = {}
        for i, obj_id in enumerate(ids):
            found: dict[str, Any] = {a: words[a][i] for a in ATTRIBUTES}
            found.update(self.affordances.get(found["name"], {a: None for a in AFFORDANCES}))
            out[obj_id] = found
        return out
