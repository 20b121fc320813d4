"""A :class:`~lagcodegen.result.Result` whose derived members are made on first access
(:class:`LazyResult`): the prepared runs of ``simulate()``'s fast path hand back the driver's
arrays and statistics struct as they are, and the statistics dict, the outputs by name and the
parameters by name are built only if the caller reads them.

A LazyResult is a Result in every respect (``isinstance``, fields, methods, ``dataclasses.replace``,
``copy``, pickling, which give a plain Result with every member made)."""

from __future__ import annotations

import dataclasses

from ..result import Result

#: The members made on first access: their makers' method names, or a plain empty list.
LAZY = {"state_names": "state_names_of", "stats": "stats", "outputs": "outputs", "parameters": "parameters",
        "events": None, "sensitivity_names": None, "sensitivity_values": None}
_FIELDS = tuple(f.name for f in dataclasses.fields(Result))


class ResultMaker:
    """What a family's prepared run knows once (names, statistics reader) to make the members of
    its LazyResults from the raw data of one run (``raw``: whatever the run kept, e.g. its
    statistics struct, outputs array and parameter array)."""

    def __init__(self, state_names, output_names, param_names):
        self.state_names = list(state_names)
        self.output_names = list(output_names)
        self.param_names = list(param_names)

    def state_names_of(self, raw) -> list:
        """The state names (a list of the result's own)."""
        return list(self.state_names)

    def stats(self, raw) -> dict:  # pragma: no cover - every family's maker defines it
        raise NotImplementedError

    def outputs(self, raw) -> dict:
        """The outputs by name: columns of the run's outputs array ``raw[1]``."""
        out = raw[1]
        return {name: out[:, i] for i, name in enumerate(self.output_names)}

    def parameters(self, raw) -> dict:
        """The run-time parameters by name from the run's parameter array ``raw[2]`` (numpy
        scalars, as a Result of the full path has them)."""
        return dict(zip(self.param_names, raw[2]))


class LazyResult(Result):
    """A Result made by a prepared run: ``state_names``, ``stats``, ``outputs``, ``parameters`` (and the empty
    ``events`` and sensitivity lists) are made from ``_raw`` by ``_maker`` when first read, then
    kept like any field (writable, e.g. ``res.stats["restarts"] = ...``)."""

    def __getattr__(self, name: str):  # called only for members not yet in the instance
        d = self.__dict__
        maker = d.get("_maker")
        if maker is None or name not in LAZY:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        how = LAZY[name]
        value = d[name] = [] if how is None else getattr(maker, how)(d["_raw"])
        return value

    def materialized(self) -> dict:
        """Every field of the Result by name, the lazy ones made."""
        return {name: getattr(self, name) for name in _FIELDS}

    def __reduce__(self):
        """Copied and pickled as a plain Result with every member made."""
        return _plain_result, (self.materialized(),)

    def __reduce_ex__(self, protocol):
        return self.__reduce__()


def _plain_result(fields: dict) -> Result:
    return Result(**fields)


def lazy_result(maker: ResultMaker, raw, fixed: dict, t, y, status: int, message: str) -> LazyResult:
    """A LazyResult of one run: ``fixed`` the members shared by every run of a prepared run
    (backend, method, n_coordinates, model_name, drawing), ``raw`` what its maker
    needs."""
    res = _new(LazyResult)
    # attribute stores first (cheaper than item stores into the instance's __dict__), then the
    # shared members
    res.t = t
    res.y = y
    res.status = status
    res.message = message
    res._maker = maker
    res._raw = raw
    res.__dict__.update(fixed)
    return res


_new = object.__new__
