"""Measured pendulum of Schmidt & Lipson (2009), the HNN paper's "real pendulum" task.

Data file: ``real_pend_h_1.txt`` from the supplement of M. Schmidt and H. Lipson,
"Distilling free-form natural laws from experimental data", Science 324:81 (2009).
Header ``%o v``, then 556 rows ``trial t theta omega`` (CRLF line endings), sampled at
dt = 1/6 s with a few gaps. It is found by :func:`hnnbench.locate` (``data_path``,
``$HNNBENCH_DATA_DIR``, the cache, ``url``, then the data set's public archive,
``archive_url``: downloaded into the cache on first use, the file extracted from it)
and checked against its SHA-256; see docs/DATA.md.

Protocol:

- State ``x = (q, p) = (theta, omega)``, as the original did (omega is the angular
  velocity, not a canonical momentum).
- Targets: forward differences ``(x[i+1] - x[i]) / (t[i+1] - t[i])`` with the *measured*
  dt, attached to ``x[i]``. A difference is dropped when it would span a gap (dt larger
  than ``max_gap_factor`` times the median dt, 10 of the 555 in the file), a trial
  boundary, or the train/test boundary; the last row has no forward difference.
- Split, by folds (docs/DATA.md, "Folds of a measured series"): the rows, in time order,
  are cut into ``folds`` equal blocks. The seed chooses the fold: fold
  ``k = (folds - 1 - seed) mod folds``, so seed 0 tests on the last block (the paper's
  test segment) and seeds 0-9 visit every fold twice. Block ``k`` is the test segment,
  the later half of the block before it (cyclically) the validation segment, the rest
  trains. At every edge between two segments, the rows within ``fold_gap_s`` seconds
  on the training or validation side are dropped, so that neighbouring, correlated
  samples never sit on both sides; every point uses rows of one segment only.
- Energy: modelled as ``2.4 (1 - cos q) + p^2``. The true vector field is unknown.
- Selection: on short rollouts over the validation segment (``selection =
  "rollout"``: the data has no clean inputs behind its measurement noise).
- Evaluation: the test segment is cut into ``eval_chunks`` contiguous, gap-free chunks of
  equal length (the paper's "5 splits"), so each metric gets a standard error. Each chunk
  is one trajectory: its first measured state is the initial state and its measured
  states are the reference. The time grid is the measured times relative to the chunk
  start (those of the first chunk; the others agree to rounding, recorded in meta).
- ``time_reversible = False``: the pendulum is damped, so the measured dynamics are not
  time-reversal symmetric even though the energy model satisfies ``H(q, -p) = H(q, p)``;
  the time-reversal metric has no valid reference here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Optional

import numpy as np

from hnnbench import (
    URL_SCHEMES,
    ConfigError,
    DataArchive,
    DataError,
    Dataset,
    Kinematics,
    Split,
    System,
    SystemConfig,
    Trajectories,
    identity_kinematics,
    locate,
)

#: The file's name in the Schmidt & Lipson data set.
FILENAME = "real_pend_h_1.txt"
#: SHA-256 of the published file (from the data set's SHA256SUMS).
SHA256 = "45d92988198b89a5933f5a53e67aa819d06937516f71a462ac09e1307d8b3411"
#: Columns of a data row.
COLUMNS = ("trial", "t", "theta", "omega")
#: A public copy of the data set's archive ``invar_datasets.zip``: the file as committed
#: to the Symplectic-ODENet repository (Zhong et al. 2020; removed from its later
#: commits, so the URL names the commit). Its members lie at the archive's top level.
ARCHIVE_URL = (
    "https://raw.githubusercontent.com/Physics-aware-AI/Symplectic-ODENet/"
    "5e83faf93e8f4990e63821c49d0ce5926a96cc94/experiment-real/invar_datasets.zip"
)
#: SHA-256 of ``invar_datasets.zip`` (the shared data set's README).
ARCHIVE_SHA256 = "9794ee02f45403f87b739cc235a046bd424a73b8222067165f66463cef57be59"
#: Energy model E = A (1 - cos q) + p^2.
ENERGY_A = 2.4


@dataclass
class RealPendulumConfig(SystemConfig):
    """Paper settings: 2000 full-batch steps, weight decay 1e-5; one fifth of the series
    tests (seed 0: the last fifth, as the paper)."""

    #: The data file, or a directory holding it (None: $HNNBENCH_DATA_DIR, then cache).
    data_path: Optional[str] = None
    #: Full URL of the file itself, tried when no local copy exists. None: none (the
    #: paper's URL is dead).
    url: Optional[str] = None
    #: The data set's archive, downloaded into the cache when no copy of the file exists
    #: (the file is extracted from it). None: no download.
    archive_url: Optional[str] = ARCHIVE_URL
    #: The archive's SHA-256 (each file extracted is checked against its own too).
    archive_sha256: str = ARCHIVE_SHA256
    #: Network timeout of the download, in seconds.
    download_timeout_s: float = 30.0
    #: Blocks the series is cut into; the seed's fold tests on one of them.
    folds: int = 5
    #: Seconds of rows dropped beside each edge between segments (training or
    #: validation side).
    fold_gap_s: float = 0.25
    #: A sampling interval above this many median intervals is a gap (not differenced).
    max_gap_factor: float = 1.5
    #: Number of contiguous chunks of the test segment used as evaluation trajectories.
    eval_chunks: int = 5
    steps: int = 2000
    batch_size: Optional[int] = None
    weight_decay: float = 1e-5

    #: Fields that say where to find the file, not what it holds: not part of the key.
    LOCATION_FIELDS: ClassVar[tuple[str, ...]] = (
        "data_path",
        "url",
        "archive_url",
        "archive_sha256",
        "download_timeout_s",
    )

    def data_fields(self) -> dict[str, Any]:
        """The dataset cache key: the file's hash instead of where it was found."""
        out = super().data_fields()
        for key in self.LOCATION_FIELDS:
            out.pop(key, None)
        out["sha256"] = SHA256
        return out

    def validate(self) -> None:
        super().validate()
        if isinstance(self.folds, bool) or not isinstance(self.folds, int) or self.folds < 2:
            raise ConfigError(
                f"system.folds={self.folds} is invalid: expected an integer >= 2, e.g. "
                "system.folds=5."
            )
        if not (self.fold_gap_s >= 0 and math.isfinite(self.fold_gap_s)):
            raise ConfigError(
                f"system.fold_gap_s={self.fold_gap_s} is invalid: expected a number of "
                "seconds >= 0, e.g. system.fold_gap_s=0.25."
            )
        if not self.max_gap_factor > 1.0:
            raise ConfigError(
                f"system.max_gap_factor={self.max_gap_factor} is invalid: expected a number "
                "> 1 (multiples of the median sampling interval), e.g. 1.5."
            )
        if not self.download_timeout_s > 0:
            raise ConfigError(
                f"system.download_timeout_s={self.download_timeout_s} is invalid: expected "
                "a number of seconds > 0."
            )
        if (
            isinstance(self.eval_chunks, bool)
            or not isinstance(self.eval_chunks, int)
            or (self.eval_chunks < 1)
        ):
            raise ConfigError(
                f"system.eval_chunks={self.eval_chunks} is invalid: expected an integer "
                ">= 1, e.g. system.eval_chunks=5."
            )
        for key in ("url", "archive_url"):
            value = getattr(self, key)
            if value is not None and str(value).split(":", 1)[0].lower() not in URL_SCHEMES:
                raise ConfigError(
                    f"system.{key}={value} is invalid: expected a full URL starting with "
                    f"{', '.join(s + '://' for s in URL_SCHEMES)}, or null for no download."
                )
        digest = str(self.archive_sha256).lower()
        if len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest):
            raise ConfigError(
                f"system.archive_sha256={self.archive_sha256} is invalid: expected the "
                "archive's SHA-256, 64 hexadecimal digits."
            )


def parse_table(
    path: Path,
    filename: str,
    columns: tuple[str, ...],
    *,
    column_labels: Optional[str] = None,
    expected_rows: str = "hundreds",
) -> np.ndarray:
    """Read a measured table of Schmidt & Lipson's data set: ``(N, len(columns))`` float64
    rows, the first two columns ``trial`` and ``t`` (seconds).

    Args:
        path: the file.
        filename: the data set's name of the file, for the messages.
        columns: the column names, in file order.
        column_labels: how the messages list the columns (default: ``columns`` joined
            with commas).
        expected_rows: how many data rows the original has, in words, for the messages.

    Lines starting with ``%`` are headers; CRLF and LF endings both work. Raises a
    one-line DataError naming the file and line for anything malformed, and for times
    that do not increase within a trial.
    """
    labels = ", ".join(columns) if column_labels is None else column_labels
    try:
        text = Path(path).read_bytes().decode("ascii")
    except UnicodeDecodeError as exc:
        raise DataError(
            f"Data file {path} is not a text table (non-ASCII byte at offset {exc.start}). "
            f"Replace it with the original {filename}."
        ) from None
    except OSError as exc:
        raise DataError(f"Cannot read data file {path}: {exc.strerror or exc}.") from None
    rows: list[list[float]] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("%"):
            continue
        fields = line.split()
        bad = f"Data file {path}, line {lineno}"
        if len(fields) != len(columns):
            raise DataError(
                f"{bad}: expected {len(columns)} columns ({labels}), got {len(fields)}. The "
                f"file is truncated or not {filename}; replace it with the original."
            )
        try:
            values = [float(v) for v in fields]
        except ValueError:
            raise DataError(
                f"{bad}: non-numeric value in {line[:60]!r}. The file is corrupt; replace "
                f"it with the original {filename}."
            ) from None
        if not all(np.isfinite(values)):
            raise DataError(f"{bad}: non-finite value. Replace it with the original file.")
        rows.append(values)
    if len(rows) < 3:
        raise DataError(
            f"Data file {path} has {len(rows)} data rows; expected {expected_rows}. Replace "
            f"it with the original {filename}."
        )
    table = np.asarray(rows, dtype=np.float64)
    trial, t = table[:, 0], table[:, 1]
    same = trial[1:] == trial[:-1]
    if np.any(np.diff(t)[same] <= 0):
        row = int(np.flatnonzero(same & (np.diff(t) <= 0))[0]) + 2
        raise DataError(
            f"Data file {path}: times do not increase within a trial (data row {row}). "
            f"Replace it with the original {filename}."
        )
    return table


class MeasuredTableSystem(System):
    """Base of the systems whose data is one checksummed table of measured trials, one
    row per sample: ``trial, t, ...`` (the real pendulum, the real double pendulum).

    It locates and verifies the file (:func:`hnnbench.locate`), finds its sampling
    interval and gaps (:meth:`_structure`), assigns rows to the training, validation and
    test segments of a seed's fold (:meth:`_segments`), and cuts the test segment into
    gap-free evaluation chunks (:meth:`_chunks`). A subclass sets
    ``data_file``, ``data_sha256``, ``data_columns`` (and, for the parser's messages,
    ``data_column_labels`` and ``data_expected_rows``), read by :meth:`parse`
    (:func:`parse_table`); its config has the fields of :class:`RealPendulumConfig`.
    """

    data_file: ClassVar[str]
    data_sha256: ClassVar[str]
    data_columns: ClassVar[tuple[str, ...]]
    data_column_labels: ClassVar[Optional[str]] = None
    data_expected_rows: ClassVar[str] = "hundreds"
    cfg: RealPendulumConfig
    # A measured device loses energy (damping) and is not time-reversible.
    time_reversible = False
    conservative = False
    # No clean inputs behind the measurement noise: select on short rollouts.
    selection = "rollout"
    profiles = {"quick": {"steps": 300}}

    def __init__(self, cfg: SystemConfig) -> None:
        super().__init__(cfg)
        self._loaded: Optional[tuple[Path, np.ndarray]] = None

    @classmethod
    def parse(cls, path: Path) -> np.ndarray:
        """The table of ``path``, ``(rows, len(data_columns))`` (:func:`parse_table`);
        raise DataError if malformed."""
        return parse_table(
            path,
            cls.data_file,
            cls.data_columns,
            column_labels=cls.data_column_labels,
            expected_rows=cls.data_expected_rows,
        )

    def load(self) -> tuple[Path, np.ndarray]:
        """Locate, verify and parse the data file (once per instance)."""
        if self._loaded is None:
            c = self.cfg
            archive = (
                DataArchive(str(c.archive_url), str(c.archive_sha256)) if c.archive_url else None
            )
            path = locate(
                self.data_file,
                sha256=self.data_sha256,
                explicit=c.data_path,
                url=c.url,
                timeout_s=c.download_timeout_s,
                archive=archive,
            )
            self._loaded = (path, self.parse(path))
        return self._loaded

    def _structure(self) -> dict[str, Any]:
        """Rows, sampling, gaps and the train/test boundary of the data file."""
        path, table = self.load()
        trial, t = table[:, 0], table[:, 1]
        n = len(table)
        same_trial = trial[1:] == trial[:-1]
        steps = np.diff(t)
        dt = float(np.median(steps[same_trial])) if same_trial.any() else float("nan")
        if not dt > 0:
            raise DataError(f"Data file {path}: cannot determine its sampling interval.")
        gap = same_trial & (steps > self.cfg.max_gap_factor * dt)
        # contiguous[i]: rows i and i+1 are consecutive samples of one trial.
        contiguous = same_trial & ~gap
        if n < 4 * self.cfg.folds:
            raise ConfigError(
                f"system.folds={self.cfg.folds} is too many for the {n} rows of {path}: "
                "each block needs a few rows. Use fewer folds."
            )
        return {
            "path": path,
            "table": table,
            "dt": dt,
            "n_rows": n,
            "gap": gap,
            "trial_boundary": ~same_trial,
            "contiguous": contiguous,
        }

    def fold(self, seed: int) -> int:
        """The fold of ``seed``: ``(folds - 1 - seed) mod folds`` (seed 0: the last block,
        the paper's test segment)."""
        return (self.cfg.folds - 1 - int(seed)) % self.cfg.folds

    def _segments(self, s: dict[str, Any], seed: int) -> dict[str, Any]:
        """Which rows of the series train, validate and test under ``seed``'s fold.

        Returns ``role`` ``(n,)`` (0 train, 1 validation, 2 test, -1 dropped at an edge),
        the test block ``(start, stop)`` and the rule in words (the dataset's meta)."""
        n, folds = s["n_rows"], self.cfg.folds
        k = self.fold(seed)
        edges = [round(i * n / folds) for i in range(folds + 1)]
        role = np.zeros(n, dtype=np.int64)
        test = (edges[k], edges[k + 1])
        role[test[0] : test[1]] = 2
        before = (k - 1) % folds
        valid = ((edges[before] + edges[before + 1]) // 2, edges[before + 1])
        role[valid[0] : valid[1]] = 1
        gap = int(math.ceil(self.cfg.fold_gap_s / s["dt"] - 1e-9))
        out = role.copy()
        for edge in np.flatnonzero(role[1:] != role[:-1]) + 1:  # rows edge-1 | edge
            for side in (np.arange(edge - gap, edge), np.arange(edge, edge + gap)):
                side = side[(side >= 0) & (side < n)]
                out[side[role[side] != 2]] = -1
        rule = (
            f"fold {k} of {folds} (seed {seed}): rows {test[0]}-{test[1] - 1} test, rows "
            f"{valid[0]}-{valid[1] - 1} validate (the later half of the block before), "
            f"the rest train; {gap} rows ({self.cfg.fold_gap_s:g} s) dropped beside "
            "each edge on the training or validation side"
        )
        return {"role": out, "fold": k, "test": test, "valid": valid, "gap_rows": gap, "rule": rule}

    def _chunks(self, s: dict[str, Any], seed: int) -> tuple[list[int], int, dict[str, Any]]:
        """The evaluation chunks of ``seed``'s test segment: ``eval_chunks`` runs of
        equal length, each inside one gap-free run of rows, as long as that count allows.

        Returns ``(start rows, chunk length, grid)``, where ``grid`` holds ``t``, the
        first chunk's time grid ``(length,)``, and the chunk-layout entries of the
        evaluation's meta.
        """
        table, contiguous = s["table"], s["contiguous"]
        n_chunks = self.cfg.eval_chunks
        first, stop = self._segments(s, seed)["test"]
        # Gap-free runs of rows inside the test segment, as (start, stop) row ranges.
        runs: list[tuple[int, int]] = []
        start = first
        for row in range(first, stop):
            if row == stop - 1 or not contiguous[row]:
                runs.append((start, row + 1))
                start = row + 1
        lengths = np.array([stop - begin for begin, stop in runs])
        # The longest chunk length that still yields n_chunks chunks.
        length = next(
            (n for n in range(int(lengths.max()), 1, -1) if int((lengths // n).sum()) >= n_chunks),
            0,
        )
        if length < 2:
            raise ConfigError(
                f"system.eval_chunks={n_chunks} is too many: the test segment "
                f"({stop - first} rows, {len(runs)} gap-free runs) cannot give "
                f"{n_chunks} chunks of at least 2 points. Use fewer chunks."
            )
        starts = [b + k * length for b, stop in runs for k in range((stop - b) // length)]
        starts = starts[:n_chunks]
        t = table[:, 1]
        grids = np.stack([t[b : b + length] - t[b] for b in starts])
        meta = {
            "source": "measured",
            "data_file": str(s["path"]),
            "sha256": self.data_sha256,
            "n_traj": len(starts),
            "chunk_points": length,
            "chunk_start_times": [float(t[b]) for b in starts],
            "horizon": float(grids[0, -1]),
            "fold": self.fold(seed),
            "test_rows": stop - first,
            "unused_test_rows": stop - first - len(starts) * length,
            "max_grid_deviation": float(np.max(np.abs(grids - grids[0]))),
        }
        return starts, length, {"t": grids[0].copy(), "meta": meta}


class RealPendulum(MeasuredTableSystem):
    """Measured pendulum (Schmidt & Lipson 2009); the HNN paper's real-pendulum task."""

    Config = RealPendulumConfig
    data_file, data_sha256, data_columns = FILENAME, SHA256, COLUMNS
    order = 30
    cfg: RealPendulumConfig
    version = "2"  # 2: seeds choose folds of the series (test, validation), selection
    description = "Measured pendulum, Schmidt & Lipson 2009, E = 2.4(1 - cos q) + p^2 (task 3)"

    @property
    def dof(self) -> int:
        return 1

    def energy(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        q, p = x[..., 0], x[..., 1]
        return ENERGY_A * (1.0 - np.cos(q)) + p**2

    def kinematics(self) -> Kinematics:
        """The state's "momentum" is the measured angular velocity: ``q̇ = p``."""
        return identity_kinematics()

    @property
    def angles(self) -> tuple[int, ...]:
        """The pendulum's angle ``θ``."""
        return (0,)

    # ------------------------------------------------------------------ data

    def dataset(self, seed: int) -> Dataset:
        """The measured points and forward-difference targets of ``seed``'s fold: train,
        validation and test segments (the module docstring)."""
        s = self._structure()
        table, contiguous = s["table"], s["contiguous"]
        seg = self._segments(s, seed)
        role = seg["role"]
        x = table[:, 2:4]
        t = table[:, 1]
        dxdt = (x[1:] - x[:-1]) / np.diff(t)[:, None]  # (n - 1, 2), attached to x[:-1]
        # A point's forward difference stays inside its segment and crosses no gap.
        same = contiguous & (role[:-1] == role[1:])

        def split(code: int) -> Split:
            idx = np.flatnonzero(same & (role[:-1] == code))
            return Split(
                x=x[idx].copy(),
                dxdt=dxdt[idx].copy(),
                traj=table[idx, 0].astype(np.int64),
                t=t[idx].copy(),
            )

        train, valid, test = split(0), split(1), split(2)
        return Dataset(
            train=train,
            test=test,
            valid=valid,
            meta={
                "data_file": str(s["path"]),
                "sha256": SHA256,
                "n_rows": s["n_rows"],
                "dt": s["dt"],
                "state": "(q, p) = (theta, omega)",
                "targets": "forward differences over the measured dt",
                "fold": seg["fold"],
                "folds": self.cfg.folds,
                "validation": seg["rule"],
                "test_rows": list(seg["test"]),
                "valid_rows": list(seg["valid"]),
                "n_train": len(train),
                "n_valid": len(valid),
                "n_test": len(test),
                "n_gaps": int(s["gap"].sum()),
                "n_dropped_at_edges": int((role == -1).sum()),
                "n_dropped_at_trial_boundaries": int(s["trial_boundary"].sum()),
                "max_gap_factor": self.cfg.max_gap_factor,
            },
        )

    def evaluation(self, seed: int) -> Trajectories:
        """``eval_chunks`` gap-free chunks of ``seed``'s measured test segment."""
        s = self._structure()
        starts, length, grid = self._chunks(s, seed)
        states = np.stack([s["table"][b : b + length, 2:4] for b in starts])
        return Trajectories(t=grid["t"], states=states, dt=s["dt"], meta=grid["meta"])
