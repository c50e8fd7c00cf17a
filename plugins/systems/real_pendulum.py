"""Measured pendulum of Schmidt & Lipson (2009), the HNN paper's "real pendulum" task.

Data file: ``real_pend_h_1.txt`` from the supplement of M. Schmidt and H. Lipson,
"Distilling free-form natural laws from experimental data", Science 324:81 (2009).
Header ``%o v``, then 556 rows ``trial t theta omega`` (CRLF line endings), sampled at
dt = 1/6 s with a few gaps. It is found by :func:`hnnbench.locate` (``data_path``,
``$HNNBENCH_DATA_DIR``, the cache, then ``url``) and checked against its SHA-256. The
paper's download URL is dead and no live public mirror is known, so ``url`` defaults
to ``None``; see docs/DATA.md.

Protocol:

- State ``x = (q, p) = (theta, omega)``, as the original did (omega is the angular
  velocity, not a canonical momentum).
- Targets: forward differences ``(x[i+1] - x[i]) / (t[i+1] - t[i])`` with the *measured*
  dt, attached to ``x[i]``. A difference is dropped when it would span a gap (dt larger
  than ``max_gap_factor`` times the median dt, 10 of the 555 in the file), a trial
  boundary, or the train/test boundary; the last row has no forward difference.
- Split: the first ``1 - test_split`` of the rows (in time order) are the training
  segment, the last ``test_split`` the test segment; every point uses rows of one
  segment only.
- Energy: modelled as ``2.4 (1 - cos q) + p^2``. The true vector field is unknown.
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

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Optional

import numpy as np

from hnnbench import (
    URL_SCHEMES,
    ConfigError,
    DataError,
    Dataset,
    Kinematics,
    Split,
    System,
    SystemConfig,
    Trajectories,
    TrajectorySplit,
    identity_kinematics,
    locate,
)

#: The file's name in the Schmidt & Lipson data set.
FILENAME = "real_pend_h_1.txt"
#: SHA-256 of the published file (from the data set's SHA256SUMS).
SHA256 = "45d92988198b89a5933f5a53e67aa819d06937516f71a462ac09e1307d8b3411"
#: Columns of a data row.
COLUMNS = ("trial", "t", "theta", "omega")
#: Energy model E = A (1 - cos q) + p^2.
ENERGY_A = 2.4


@dataclass
class RealPendulumConfig(SystemConfig):
    """Paper settings: 2000 full-batch steps, weight decay 1e-5, last 20% tests."""

    #: The data file, or a directory holding it (None: $HNNBENCH_DATA_DIR, then cache).
    data_path: Optional[str] = None
    #: Full URL to download the file from when no local copy exists. None: no download
    #: (the paper's URL is dead and no live public mirror is known).
    url: Optional[str] = None
    #: Network timeout of the download, in seconds.
    download_timeout_s: float = 30.0
    #: Fraction of the rows, at the end of the sequence, that forms the test segment.
    test_split: float = 0.2
    #: A sampling interval above this many median intervals is a gap (not differenced).
    max_gap_factor: float = 1.5
    #: Number of contiguous chunks of the test segment used as evaluation trajectories.
    eval_chunks: int = 5
    steps: int = 2000
    batch_size: Optional[int] = None
    weight_decay: float = 1e-5

    #: Fields that say where to find the file, not what it holds: not part of the key.
    LOCATION_FIELDS: ClassVar[tuple[str, ...]] = ("data_path", "url", "download_timeout_s")

    def data_fields(self) -> dict[str, Any]:
        """The dataset cache key: the file's hash instead of where it was found."""
        out = super().data_fields()
        for key in self.LOCATION_FIELDS:
            out.pop(key, None)
        out["sha256"] = SHA256
        return out

    def validate(self) -> None:
        super().validate()
        if not 0.0 < self.test_split < 1.0:
            raise ConfigError(
                f"system.test_split={self.test_split} is invalid: expected a fraction "
                "strictly between 0 and 1, e.g. system.test_split=0.2."
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
        if isinstance(self.eval_chunks, bool) or not isinstance(self.eval_chunks, int) or (
            self.eval_chunks < 1
        ):
            raise ConfigError(
                f"system.eval_chunks={self.eval_chunks} is invalid: expected an integer "
                ">= 1, e.g. system.eval_chunks=5."
            )
        if self.url is not None and str(self.url).split(":", 1)[0].lower() not in URL_SCHEMES:
            raise ConfigError(
                f"system.url={self.url} is invalid: expected a full URL starting with "
                f"{', '.join(s + '://' for s in URL_SCHEMES)}, or null for no download."
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
    interval, gaps and train/test boundary (:meth:`_structure`), and cuts the test
    segment into gap-free evaluation chunks (:meth:`_chunks`). A subclass sets
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
    profiles = {"quick": {"steps": 300}}

    def __init__(self, cfg: SystemConfig) -> None:
        super().__init__(cfg)
        self._loaded: Optional[tuple[Path, np.ndarray]] = None

    @classmethod
    def parse(cls, path: Path) -> np.ndarray:
        """The table of ``path``, ``(rows, len(data_columns))`` (:func:`parse_table`);
        raise DataError if malformed."""
        return parse_table(
            path, cls.data_file, cls.data_columns, column_labels=cls.data_column_labels,
            expected_rows=cls.data_expected_rows,
        )

    def load(self) -> tuple[Path, np.ndarray]:
        """Locate, verify and parse the data file (once per instance)."""
        if self._loaded is None:
            c = self.cfg
            path = locate(
                self.data_file, sha256=self.data_sha256, explicit=c.data_path, url=c.url,
                timeout_s=c.download_timeout_s,
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
        # The last round(n * test_split) rows, in time order, form the test segment.
        split_row, _ = TrajectorySplit(self.cfg.test_split, test_from="last").sizes(n)
        if not 2 <= split_row <= n - 2:
            raise ConfigError(
                f"system.test_split={self.cfg.test_split} leaves an empty train or test "
                f"segment of the {n} rows: choose a fraction nearer 0.2."
            )
        return {
            "path": path, "table": table, "dt": dt, "n_rows": n, "gap": gap,
            "trial_boundary": ~same_trial, "contiguous": contiguous, "split_row": split_row,
        }

    def _chunks(self, s: dict[str, Any]) -> tuple[list[int], int, dict[str, Any]]:
        """The evaluation chunks of the test segment: ``eval_chunks`` runs of equal
        length, each inside one gap-free run of rows, as long as that count allows.

        Returns ``(start rows, chunk length, grid)``, where ``grid`` holds ``t``, the
        first chunk's time grid ``(length,)``, and the chunk-layout entries of the
        evaluation's meta.
        """
        table, contiguous, split_row = s["table"], s["contiguous"], s["split_row"]
        n_rows, n_chunks = s["n_rows"], self.cfg.eval_chunks
        # Gap-free runs of rows inside the test segment, as (start, stop) row ranges.
        runs: list[tuple[int, int]] = []
        start = split_row
        for row in range(split_row, n_rows):
            if row == n_rows - 1 or not contiguous[row]:
                runs.append((start, row + 1))
                start = row + 1
        lengths = np.array([stop - begin for begin, stop in runs])
        # The longest chunk length that still yields n_chunks chunks.
        length = next(
            (n for n in range(int(lengths.max()), 1, -1)
             if int((lengths // n).sum()) >= n_chunks),
            0,
        )
        if length < 2:
            raise ConfigError(
                f"system.eval_chunks={n_chunks} is too many: the test segment "
                f"({n_rows - split_row} rows, {len(runs)} gap-free runs) cannot give "
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
            "test_rows": n_rows - split_row,
            "unused_test_rows": n_rows - split_row - len(starts) * length,
            "max_grid_deviation": float(np.max(np.abs(grids - grids[0]))),
        }
        return starts, length, {"t": grids[0].copy(), "meta": meta}


class RealPendulum(MeasuredTableSystem):
    """Measured pendulum (Schmidt & Lipson 2009); the HNN paper's real-pendulum task."""

    Config = RealPendulumConfig
    data_file, data_sha256, data_columns = FILENAME, SHA256, COLUMNS
    order = 30
    cfg: RealPendulumConfig
    version = "1"
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
        """The measured points and forward-difference targets (``seed`` is unused)."""
        s = self._structure()
        table, contiguous, split_row = s["table"], s["contiguous"], s["split_row"]
        x = table[:, 2:4]
        t = table[:, 1]
        dxdt = (x[1:] - x[:-1]) / np.diff(t)[:, None]  # (n - 1, 2), attached to x[:-1]
        i = np.arange(len(dxdt))
        across_split = i == split_row - 1
        train_idx = np.flatnonzero(contiguous & (i < split_row - 1))
        test_idx = np.flatnonzero(contiguous & (i >= split_row))

        def split(idx: np.ndarray) -> Split:
            return Split(
                x=x[idx].copy(), dxdt=dxdt[idx].copy(),
                traj=table[idx, 0].astype(np.int64), t=t[idx].copy(),
            )

        return Dataset(
            train=split(train_idx),
            test=split(test_idx),
            meta={
                "data_file": str(s["path"]),
                "sha256": SHA256,
                "n_rows": s["n_rows"],
                "dt": s["dt"],
                "state": "(q, p) = (theta, omega)",
                "targets": "forward differences over the measured dt",
                "split_row": split_row,
                "split_time": float(t[split_row]),
                "n_train": int(len(train_idx)),
                "n_test": int(len(test_idx)),
                "n_gaps": int(s["gap"].sum()),
                "n_dropped_at_gaps": int(s["gap"].sum()),
                "n_dropped_at_trial_boundaries": int(s["trial_boundary"].sum()),
                "n_dropped_at_split": int(contiguous[across_split].sum()),
                "max_gap_factor": self.cfg.max_gap_factor,
            },
        )

    def evaluation(self, seed: int) -> Trajectories:
        """``eval_chunks`` gap-free chunks of the measured test segment (``seed`` unused)."""
        s = self._structure()
        starts, length, grid = self._chunks(s)
        states = np.stack([s["table"][b : b + length, 2:4] for b in starts])
        return Trajectories(t=grid["t"], states=states, dt=s["dt"], meta=grid["meta"])
