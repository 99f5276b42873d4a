"""A minimal FieldBatch (the contract of acl/sweep/perturb.py) and a materialiser, for the evaluate tests.

``materialize`` rebuilds point i as a plain Design with pydantic ``model_copy`` (the slow, obviously
correct way), so that `acl analyze` on it can be compared with the batched columns.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def nominal(design, path: str) -> float:
    obj = design
    for part in path.split("."):
        if isinstance(obj, tuple) and part.isdigit():
            obj = obj[int(part)]
        elif isinstance(obj, tuple):
            obj = next(x for x in obj if getattr(x, "name", None) == part)
        else:
            obj = getattr(obj, part)
    return float(obj)


@dataclass(frozen=True)
class FieldBatch:
    design: object
    n: int
    fields: dict
    valid: np.ndarray
    code: np.ndarray

    def get(self, path: str) -> np.ndarray:
        if path in self.fields:
            return self.fields[path]
        return np.full(self.n, nominal(self.design, path))


def make_batch(design, fields: dict, valid=None) -> FieldBatch:
    fields = {k: np.asarray(v, float) for k, v in fields.items()}
    n = len(next(iter(fields.values())))
    valid = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
    code = np.where(valid, "", "E-TEST")
    return FieldBatch(design, n, fields, valid, code)


def _set(obj, parts: list[str], value: float):
    head, rest = parts[0], parts[1:]
    if isinstance(obj, tuple):
        if head.isdigit():
            k = int(head)
            items = list(obj)
            items[k] = value if not rest else _set(items[k], rest, value)
            return tuple(items)
        return tuple(_set(x, rest, value) if getattr(x, "name", None) == head else x for x in obj)
    if not rest:
        return obj.model_copy(update={head: value})
    return obj.model_copy(update={head: _set(getattr(obj, head), rest, value)})


def materialize(batch: FieldBatch, i: int):
    d = batch.design
    for path, arr in batch.fields.items():
        d = _set(d, path.split("."), float(arr[i]))
    # Design._index is a functools.cached_property: model_copy copies it, so lookups such as
    # design.beam(name) would return the nominal element; drop it so it is rebuilt
    d.__dict__.pop("_index", None)
    return d
