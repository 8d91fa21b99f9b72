"""A policy exported by ``dupac export`` (``policy.safetensors`` + ``policy.json``), run in NumPy.

This module needs neither the Rust core nor this repository's code: copy it beside an export
to run the policy anywhere NumPy runs. The forward pass is the one ``policy.json`` describes
(its ``forward`` field) and the one the Rust actors run; it agrees with
:meth:`dupac.Policy.act` to 1e-5 (python/tests/test_export.py).

    pol = ExportedPolicy.load("out/export")      # the directory dupac export wrote
    move, site = pol.act(obs)                    # obs: the raw observation (obs_dim,)
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

_DTYPES = {"F32": np.float32, "F64": np.float64}


def read_safetensors(path: str | Path) -> dict[str, np.ndarray]:
    """Every tensor of a safetensors file (F32 and F64 only): an 8-byte little-endian header
    length, a JSON header of ``{name: {dtype, shape, data_offsets}}``, then the data."""
    raw = Path(path).read_bytes()
    (n,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8 : 8 + n])
    data = memoryview(raw)[8 + n :]
    out = {}
    for name, info in header.items():
        if name == "__metadata__":
            continue
        begin, end = info["data_offsets"]
        dtype = _DTYPES[info["dtype"]]
        out[name] = np.frombuffer(data[begin:end], dtype=dtype).reshape(info["shape"]).copy()
    return out


class ExportedPolicy:
    """The networks and constants of an export, and their forward pass."""

    def __init__(self, meta: dict, tensors: dict[str, np.ndarray]) -> None:
        if meta.get("format") != "dupac-policy" or meta.get("format_version") != 1:
            raise ValueError(
                f"not a dupac-policy export of format_version 1: {meta.get('format')!r} "
                f"{meta.get('format_version')!r}"
            )
        self.meta = meta
        self.t = tensors
        self.obs_dim = int(meta["obs_dim"])
        self.trunk_dim = int(meta["trunk_dim"])
        self.n_sites = int(meta["n_sites"])
        self.site_head = meta["site_head"]
        self.site_features = int(meta["site_features"])

    @classmethod
    def load(cls, directory: str | Path) -> "ExportedPolicy":
        d = Path(directory)
        meta = json.loads((d / "policy.json").read_text())
        return cls(meta, read_safetensors(d / "policy.safetensors"))

    def _mlp(self, name: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The MLP's output and the input of its last layer (tanh after all layers but it)."""
        k = 0
        while f"{name}.{k}.weight" in self.t:
            k += 1
        for i in range(k):
            last_in = x
            x = x @ self.t[f"{name}.{i}.weight"] + self.t[f"{name}.{i}.bias"]
            if i < k - 1:
                x = np.tanh(x)
        return x, last_in

    def normalise(self, obs: np.ndarray) -> np.ndarray:
        n = self.meta["obs_norm"]
        if not n["enabled"]:
            return obs.astype(np.float32)
        z = (obs.astype(np.float64) - self.t["obs_norm.mean"]) / np.sqrt(
            self.t["obs_norm.var"] + n["epsilon"]
        )
        return np.clip(z, -n["clip"], n["clip"]).astype(np.float32)

    def forward(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """The move's mean (3,), the site logits (n_sites,; empty for the base method) and the
        value of one raw observation."""
        obs = np.asarray(obs, dtype=np.float32).reshape(-1)
        if obs.shape[0] != self.obs_dim:
            raise ValueError(f"expected {self.obs_dim} observations, got {obs.shape[0]}")
        x = self.normalise(obs)[: self.trunk_dim]
        head, hidden = self._mlp("actor", x)
        mean = head[:3]
        if self.site_head == "equivariant":
            e = np.tanh(hidden @ self.t["site_head.embed.weight"] + self.t["site_head.embed.bias"])
            f = obs[self.trunk_dim :].reshape(self.n_sites, self.site_features)
            z = np.concatenate([f, np.broadcast_to(e, (self.n_sites, e.shape[0]))], axis=1)
            logits, _ = self._mlp("site_head.mlp", z)
            logits = logits[:, 0]
        else:
            logits = head[3:]
        value, _ = self._mlp("critic", x)
        return mean, logits, float(value[0])

    def act(self, obs: np.ndarray) -> tuple[np.ndarray, int]:
        """The deterministic action: the move's mean (3,) and the first arg-max site (0 without a
        site choice)."""
        mean, logits, _ = self.forward(obs)
        return mean, int(np.argmax(logits)) if logits.size else 0
