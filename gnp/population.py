"""A population of GNP individuals as a struct of numpy arrays with a leading axis N."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gnp.config import (
    JUDGMENT,
    MIDPOINT_ALPHA,
    MIDPOINT_BETA,
    PROCESSING,
    SENSOR_MAX,
    SPEED_MAX,
    GnpConfig,
    GnpError,
)

#: Q values are stored in single precision (computed in double, rounded on store): half the
#: memory the engine reads per visit; Q values of a few units keep 7 significant digits.
Q_DTYPE = np.float32
#: Narrow integer genes: the engine is memory-latency bound, and int32 genes made it ~1.6x
#: slower for 300 individuals (bench/engine.py).
GENE_DTYPES: dict[str, type[np.signedinteger]] = {
    "function": np.int8,
    "mu_beta": np.int16,
    "mu_alpha": np.int16,
    "speed": np.int8,
    "conn": np.int16,
    "credit": np.int16,
}


@dataclass(frozen=True)
class Population:
    """N individuals of V nodes with m sub nodes each; every array has the leading axis N.

    Axes: V nodes (0 = start, then judgment, then processing; see `GnpConfig.node_type`),
    m sub nodes, k branches (`GnpConfig.judgment_branches`, 2 by default: A = 0, B = 1, …;
    processing nodes use A only), U branch connections (`GnpConfig.n_conn_branches`: U for BS,
    1 otherwise). Parts a node type or method does not
    use hold valid but unused values, so every method shares one layout.

    Attributes:
        function: (N, V, m) sensor 0..7 judged (judgment) or wheel set (processing:
            0 = right wheel P0, 1 = left wheel P1); 0 for the start node.
        mu_beta: (N, V, m) β of the judgment membership function, 0 ≤ β ≤ α.
        mu_alpha: (N, V, m) α of the judgment membership function, ≤ 1023.
        speed: (N, V, m) wheel speed −10..10 set by a processing sub node.
        conn: (N, V, m, k, U) next node per branch and branch connection; the start node uses
            conn[:, 0, 0, 0, 0].
        credit: (N, V, m) next node through the credit branch (CS).
        q_ss: (N, V, m) Q_SS(i, ip), sub node selection.
        q_bs: (N, V, m, k, U) Q_BS(C_ip^A|B|…, b^(u)), branch connection selection (BS).
        q_cs: (N, V, m, 2) Q_CS(ip, b_N) at [..., 0] and Q_CS(ip, b_C) at [..., 1] (CS).
        records: (N, V) the memory behind every field above, one record a node (see
            `record_dtype`): the fields are views into it, so writing a field writes here.
        record_bytes: the same memory as one flat uint8 array, as compiled code reads it.

    The constructor copies the arrays it is given into fresh records, so a Population never
    shares memory with its inputs.
    """

    function: np.ndarray
    mu_beta: np.ndarray
    mu_alpha: np.ndarray
    speed: np.ndarray
    conn: np.ndarray
    credit: np.ndarray
    q_ss: np.ndarray
    q_bs: np.ndarray
    q_cs: np.ndarray
    records: np.ndarray = field(init=False, repr=False, compare=False)
    record_bytes: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._adopt(_pack({f: getattr(self, f) for f in FIELDS}))

    def _adopt(self, records: np.ndarray) -> None:
        """Make `records` this population's memory: every field a view into it."""
        object.__setattr__(self, "records", records)
        object.__setattr__(self, "record_bytes", records.reshape(-1).view(np.uint8))
        for f in FIELDS:
            object.__setattr__(self, f, records[f])

    @classmethod
    def from_records(cls, records: np.ndarray, index: np.ndarray | None = None) -> Population:
        """A population over a fresh, aligned copy of (N, V) records (rows `index` only, if
        given): one block copy, no per-field repacking. The records' dtype must be the
        `record_dtype` of their shape, as `Population.records` is."""
        rows = records.shape[0] if index is None else len(index)
        fresh = _aligned_records(records.dtype, rows, records.shape[1])
        if index is None:
            fresh[...] = records
        else:
            np.take(records, index, axis=0, out=fresh)
        pop = object.__new__(cls)
        pop._adopt(fresh)
        return pop

    def __reduce__(self) -> tuple[object, tuple[np.ndarray]]:
        # Pickled (to a worker process) as its records; unpickled into aligned memory.
        return (Population.from_records, (self.records,))

    @property
    def size(self) -> int:
        """Number of individuals N."""
        return int(self.function.shape[0])

    def __len__(self) -> int:
        return self.size

    def copy(self) -> Population:
        """A deep copy (every array copied)."""
        return Population.from_records(self.records)


FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(Population) if f.init)
Q_FIELDS = ("q_ss", "q_bs", "q_cs")
#: Bytes of a cache line: records are aligned to it and padded to whole lines.
CACHE_LINE = 64


def field_shapes_per_node(
    n_sub: int, n_conn_branches: int, judgment_branches: int
) -> dict[str, tuple[int, ...]]:
    """Shape of every Population field within one node (without the leading N, V)."""
    m, u, k = n_sub, n_conn_branches, judgment_branches
    return {
        "function": (m,),
        "mu_beta": (m,),
        "mu_alpha": (m,),
        "speed": (m,),
        "conn": (m, k, u),
        "credit": (m,),
        "q_ss": (m,),
        "q_bs": (m, k, u),
        "q_cs": (m, 2),
    }


@functools.cache  # one dtype object per shape: the engine checks it by identity first
def record_dtype(n_sub: int, n_conn_branches: int, judgment_branches: int) -> np.dtype:
    """One node's genes and Q values side by side: the engine's unit of memory traffic.

    A visit reads the node's Q_SS values, then the chosen sub node's genes and its Q_BS or
    Q_CS values. Kept in nine separate arrays these are six or seven cache lines apart; in one
    record they are one line (RL, CS) or two neighbouring lines (BS, U = 2) with the default
    shape. Widest fields first keep every field aligned, and the record is padded to whole
    cache lines so that no node straddles more lines than it must.
    """
    shapes = field_shapes_per_node(n_sub, n_conn_branches, judgment_branches)
    names = sorted(FIELDS, key=lambda f: -np.dtype(field_dtype(f)).itemsize)  # stable sort
    offsets, offset = [], 0
    for name in names:
        offsets.append(offset)
        offset += np.dtype(field_dtype(name)).itemsize * math.prod(shapes[name])
    return np.dtype(
        {
            "names": names,
            "formats": [(field_dtype(f), shapes[f]) for f in names],
            "offsets": offsets,
            "itemsize": -(-offset // CACHE_LINE) * CACHE_LINE,
        }
    )


def _aligned_records(dtype: np.dtype, n: int, v: int) -> np.ndarray:
    """Zeroed (n, v) records of `dtype` starting on a cache line."""
    size = n * v * dtype.itemsize
    raw = np.zeros(size + CACHE_LINE, np.uint8)
    start = -raw.ctypes.data % CACHE_LINE
    return raw[start : start + size].view(dtype).reshape(n, v)


def _pack(arrays: dict[str, np.ndarray]) -> np.ndarray:
    """Fresh, cache-line aligned (N, V) records holding copies of the field arrays."""
    for f in FIELDS:
        if not isinstance(arrays[f], np.ndarray):
            raise GnpError(f"population field {f!r} is not a numpy array")
    function, conn = arrays["function"], arrays["conn"]
    if function.ndim != 3 or conn.ndim != 5:
        raise GnpError(
            "population fields 'function' and 'conn' need shapes (N, V, m) and (N, V, m, k, U), "
            f"got {function.shape} and {conn.shape}"
        )
    n, v, m = function.shape
    k, u = conn.shape[3:]
    for f, shape in field_shapes_per_node(m, u, k).items():
        if arrays[f].shape != (n, v, *shape):
            raise GnpError(
                f"population field {f!r} has shape {arrays[f].shape}, expected {(n, v, *shape)}"
            )
    records = _aligned_records(record_dtype(m, u, k), n, v)
    for f in FIELDS:
        try:
            np.copyto(records[f], arrays[f], casting="same_kind")
        except TypeError as err:
            raise GnpError(
                f"population field {f!r} must hold {np.dtype(field_dtype(f))} values, "
                f"got {arrays[f].dtype}"
            ) from err
    return records


def field_shapes(cfg: GnpConfig) -> dict[str, tuple[int, ...]]:
    """Per-individual shape (without the leading N) of every Population array."""
    per_node = field_shapes_per_node(cfg.n_sub, cfg.n_conn_branches, cfg.judgment_branches)
    return {f: (cfg.n_nodes, *shape) for f, shape in per_node.items()}


def field_dtype(name: str) -> type[np.generic]:
    """The dtype of a Population field."""
    return Q_DTYPE if name in Q_FIELDS else GENE_DTYPES[name]


def init_population(cfg: GnpConfig, n: int, rng: np.random.Generator) -> Population:
    """n random individuals (§2.3.3): balanced functions, random parameters and connections.

        Each sub node slot p of the judgment nodes holds every sensor equally often (5 per sensor
        for 40 nodes), and of the processing nodes every wheel equally often (10 per wheel for 20
        nodes), in a random order per individual. α is drawn in 1..1023 and β in 0..α−1, speeds in
        −10..10, every connection uniformly among nodes 1..V−1 (with `cfg.threshold_init` "midpoint"
    every β = 511 and α = 512 instead). Q tables start at `cfg.q0` (0).
    """
    if n < 0:
        raise GnpError(f"population size must be ≥ 0, got {n}")
    v, m, nj, npr = cfg.n_nodes, cfg.n_sub, cfg.n_judgment, cfg.n_processing
    judg = slice(1, 1 + nj)
    proc = slice(1 + nj, v)
    shapes = field_shapes(cfg)

    def balanced(count: int, kinds: int) -> np.ndarray:
        base = np.tile(np.arange(count, dtype=np.int8) % kinds, (n * m, 1))
        return rng.permuted(base, axis=1).reshape(n, m, count).transpose(0, 2, 1)

    function = np.zeros((n, v, m), GENE_DTYPES["function"])
    function[:, judg] = balanced(nj, cfg.n_inputs)
    function[:, proc] = balanced(npr, cfg.n_outputs)
    mu_alpha = np.zeros((n, v, m), GENE_DTYPES["mu_alpha"])
    mu_beta = np.zeros((n, v, m), GENE_DTYPES["mu_beta"])
    mu_alpha[:, judg] = rng.integers(1, SENSOR_MAX + 1, size=(n, nj, m))
    mu_beta[:, judg] = rng.integers(0, mu_alpha[:, judg])
    if cfg.threshold_init == "midpoint":  # drawn all the same: the other genes as uniform's
        mu_beta[:, judg], mu_alpha[:, judg] = MIDPOINT_BETA, MIDPOINT_ALPHA
    speed = np.zeros((n, v, m), GENE_DTYPES["speed"])
    speed[:, proc] = rng.integers(-SPEED_MAX, SPEED_MAX + 1, size=(n, npr, m))
    return Population(
        function=function,
        mu_beta=mu_beta,
        mu_alpha=mu_alpha,
        speed=speed,
        conn=rng.integers(1, v, size=(n, *shapes["conn"])).astype(GENE_DTYPES["conn"]),
        credit=rng.integers(1, v, size=(n, *shapes["credit"])).astype(GENE_DTYPES["credit"]),
        q_ss=np.full((n, *shapes["q_ss"]), cfg.q0, Q_DTYPE),
        q_bs=np.full((n, *shapes["q_bs"]), cfg.q0, Q_DTYPE),
        q_cs=np.full((n, *shapes["q_cs"]), cfg.q0, Q_DTYPE),
    )


def take(pop: Population, idx: Sequence[int] | np.ndarray) -> Population:
    """The individuals at `idx` (a 1-D index array or list), copied, in that order."""
    index = np.asarray(idx)
    if index.ndim != 1 or not (np.issubdtype(index.dtype, np.integer) or index.size == 0):
        raise GnpError(f"take needs a 1-D integer index, got shape {index.shape} {index.dtype}")
    if index.size and (index.min() < -pop.size or index.max() >= pop.size):
        raise GnpError(f"index out of range for a population of {pop.size}")
    return Population.from_records(pop.records, index.astype(np.intp) % max(pop.size, 1))


def concat(pops: Sequence[Population]) -> Population:
    """One population holding the individuals of `pops` in order."""
    if not pops:
        raise GnpError("concat needs at least one population")
    for f in FIELDS:
        shapes = {getattr(p, f).shape[1:] for p in pops}
        if len(shapes) > 1:
            raise GnpError(f"concat: populations disagree on the shape of {f!r}: {shapes}")
    if len({p.records.dtype for p in pops}) == 1:
        # np.concatenate would drop the records' padding: copy into aligned records instead.
        records = _aligned_records(
            pops[0].records.dtype, sum(p.size for p in pops), pops[0].records.shape[1]
        )
        start = 0
        for p in pops:
            records[start : start + p.size] = p.records
            start += p.size
        joined = object.__new__(Population)
        joined._adopt(records)
        return joined
    return Population(**{f: np.concatenate([getattr(p, f) for p in pops]) for f in FIELDS})


def population_to_arrays(pop: Population) -> dict[str, np.ndarray]:
    """The population's arrays by field name (not copied), e.g. for an HDF5 group."""
    return {f: getattr(pop, f) for f in FIELDS}


def population_from_arrays(cfg: GnpConfig, arrays: dict[str, np.ndarray]) -> Population:
    """A validated population from `population_to_arrays` output (copied, dtypes normalised).

    Raises:
        GnpError: a field is missing or unknown, has the wrong shape, is not integral where it
            must be, or the genome is invalid (see `check_population`).
    """
    missing = sorted(set(FIELDS) - set(arrays))
    extra = sorted(set(arrays) - set(FIELDS))
    if missing or extra:
        raise GnpError(f"population arrays: missing {missing}, unknown {extra}")
    out: dict[str, np.ndarray] = {}
    for f in FIELDS:
        a = np.asarray(arrays[f])
        dtype = field_dtype(f)
        if f not in Q_FIELDS:
            integral = np.issubdtype(a.dtype, np.integer) or a.size == 0
            whole = np.issubdtype(a.dtype, np.floating) and bool(np.all(a == np.round(a)))
            if not (integral or whole):
                raise GnpError(f"population field {f!r} must hold integers, got {a.dtype}")
            info = np.iinfo(GENE_DTYPES[f])
            if a.size and (a.min() < info.min or a.max() > info.max):
                raise GnpError(f"population field {f!r} holds values outside {np.dtype(dtype)}")
        elif not np.issubdtype(a.dtype, np.number):
            raise GnpError(f"population field {f!r} must be numeric, got {a.dtype}")
        out[f] = a.astype(dtype, copy=False)  # the constructor copies
    pop = Population(**out)
    check_population(cfg, pop)
    return pop


def check_population(cfg: GnpConfig, pop: Population) -> None:
    """Raise GnpError unless `pop` is a valid population for `cfg`.

    Valid: shapes and dtypes match the config; judgment functions name a sensor 0..7 and
    processing functions a wheel 0..1; 0 ≤ β ≤ α ≤ 1023 on judgment nodes; speeds in −10..10
    on processing nodes; every connection and credit branch names a node 1..V−1 (none into
    the start node); Q values finite.
    """
    n = pop.size
    for f, shape in field_shapes(cfg).items():
        a = getattr(pop, f)
        if not isinstance(a, np.ndarray):
            raise GnpError(f"population field {f!r} is not a numpy array")
        if a.shape != (n, *shape):
            raise GnpError(f"population field {f!r} has shape {a.shape}, expected {(n, *shape)}")
        if a.dtype != field_dtype(f):
            raise GnpError(f"population field {f!r} has dtype {a.dtype}, expected {field_dtype(f)}")
    types = cfg.node_type
    judg = types == JUDGMENT
    proc = types == PROCESSING
    fn = pop.function
    if np.any((fn[:, judg] < 0) | (fn[:, judg] >= cfg.n_inputs)):
        raise GnpError(f"judgment function outside sensors 0..{cfg.n_inputs - 1}")
    if np.any((fn[:, proc] < 0) | (fn[:, proc] >= cfg.n_outputs)):
        raise GnpError(f"processing function outside wheels 0..{cfg.n_outputs - 1}")
    beta, alpha = pop.mu_beta[:, judg], pop.mu_alpha[:, judg]
    if np.any(beta < 0) or np.any(alpha > SENSOR_MAX):
        raise GnpError("judgment parameters outside 0..1023")
    if np.any(beta > alpha):
        raise GnpError("judgment parameter β exceeds α")
    if np.any(np.abs(pop.speed[:, proc]) > SPEED_MAX):
        raise GnpError("processing speed outside −10..10")
    for f in ("conn", "credit"):
        a = getattr(pop, f)
        if np.any((a < 1) | (a >= cfg.n_nodes)):
            raise GnpError(f"{f}: a connection names no node in 1..{cfg.n_nodes - 1}")
    for f in Q_FIELDS:
        if not np.all(np.isfinite(getattr(pop, f))):
            raise GnpError(f"{f}: Q values must be finite")
