"""Loader for the training data written by `deepcontact generate` (format: models/README.md)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from safetensors import safe_open

FORMAT = "deepcontact-train"
# Format 2 added per-contact tensors, format 3 the solver rows and files without grids
# (models/README.md); the grids this loader reads are the same in all three.
FORMAT_VERSIONS = ("1", "2", "3")


def seed_file(data_dir: Path, seed: int) -> Path:
    return Path(data_dir) / f"pile-{seed:05d}.safetensors"


def read_header(path: Path) -> dict:
    """The string metadata of one file, with the JSON-valued fields decoded."""
    with safe_open(str(path), framework="numpy") as f:
        meta = dict(f.metadata() or {})
    if meta.get("format") != FORMAT or meta.get("format_version") not in FORMAT_VERSIONS:
        raise ValueError(f"{path}: not a {FORMAT} file of version {' or '.join(FORMAT_VERSIONS)}")
    for key in ("grid_layout", "input_channels", "output_channels", "solver"):
        meta[key] = json.loads(meta[key])
    return meta


def contact_mask(inputs: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Contact-bearing nodes: a contact normal or an impulse was spread there. [S, 1, H, W] float32."""
    normal = np.abs(inputs[:, 4:6]).sum(axis=1, keepdims=True)
    impulse = np.abs(labels).sum(axis=1, keepdims=True)
    return ((normal > 1e-6) | (impulse > 0)).astype(np.float32)


def load_seeds(data_dir: Path, seeds, every: int = 1, min_step: int = 0, carried: bool = False):
    """Stacks the grids of `seeds`, keeping every `every`-th recorded step at or after `min_step`.

    Returns (inputs [N,6,61,61], labels [N,2,61,61], mask [N,1,61,61], header of the first file);
    with `carried`, the inputs are followed by the carried-impulse grids ([N,8,61,61], format 3).
    """
    xs, ys, header = [], [], None
    for seed in seeds:
        path = seed_file(data_dir, seed)
        h = read_header(path)
        if header is None:
            header = h
        if h.get("grids", "true") != "true":
            raise ValueError(f"{path}: written with --no-grids; the CNNs need the grids")
        if h["grid_layout"] != header["grid_layout"]:
            raise ValueError(f"{path}: grid layout differs from the first file")
        with safe_open(str(path), framework="numpy") as f:
            steps = f.get_tensor("steps")
            keep = np.nonzero(steps >= min_step)[0][::every]
            x = f.get_tensor("inputs")[keep]
            if carried:
                if "carried" not in f.keys():
                    raise ValueError(f"{path}: no carried grids (format 3 with grids needed)")
                x = np.concatenate([x, f.get_tensor("carried")[keep]], axis=1)
            xs.append(x)
            ys.append(f.get_tensor("labels")[keep])
    x = np.concatenate(xs).astype(np.float32)
    y = np.concatenate(ys).astype(np.float32)
    return x, y, contact_mask(x[:, :6], y), header
