"""Records from someone else's machine (issue #28, docs/LEADERBOARD.md "Threat model"):
names that are not names, values outside what the metric declares, malformed, huge or
endless input. Each class is crafted on disk from a real record and must be refused
(naming the file and the field) or escaped, while the other records load."""

from __future__ import annotations

import copy
import io
import json
import math
import os
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import REPO
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from report_fixtures import write_run

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._contracts import names
from hnnbench._contracts.errors import ConfigError, UnsafePathError
from hnnbench._contracts.paths import safe_join
from hnnbench._record import store
from hnnbench._results import check
from hnnbench._results.report import write_report
from hnnbench._results.report.figures import make_figures
from hnnbench._results.report.markdown import md_cell, md_code, md_text
from hnnbench._results.report.tables import md_table

sys.path.insert(0, str(REPO / "scripts" / "maintainer"))
import publish_results  # noqa: E402

MARKER = "<!-- leaderboard:end -->"


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """A real record (a composed config, the installed plugins' provenance) with its
    rollout, written once: ``(record as JSON data, rollout bytes)``."""
    job = write_run(tmp_path_factory.mktemp("real"), "spring", "oracle", 0, profile="paper")
    return (
        json.loads((job / records.RECORD_NAME).read_text()),
        (job / records.ROLLOUT_NAME).read_bytes(),
    )


def _put(root: Path, rel: str, data, rollout: bytes | None = None) -> Path:
    """Write ``data`` (JSON data, or raw text/bytes) as ``root/rel/result.json``."""
    directory = root / rel
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / records.RECORD_NAME
    if isinstance(data, bytes):
        path.write_bytes(data)
    elif isinstance(data, str):
        path.write_text(data)
    else:
        path.write_text(json.dumps(data))
    if rollout is not None:
        (directory / records.ROLLOUT_NAME).write_bytes(rollout)
    return path


def _crafted(real, **changes):
    rec = copy.deepcopy(real[0])
    for key, value in changes.items():
        if "." in key:
            outer, inner = key.split(".", 1)
            rec[outer][inner] = value
        else:
            rec[key] = value
    return rec


def _reasons(loaded) -> dict[Path, str]:
    return {p.path: p.reason for p in loaded.problems}


def _one_line(reason: str) -> bool:
    return "\n" not in reason and len(reason) < 500


# --------------------------------------------------------------------------- names

BAD_NAMES = [
    "/etc",
    "../../escaped",
    "..",
    "a|b",
    "x\ny",
    "spring\n",
    MARKER,
    "Spring",
    "a" * 65,
    "",
    "sp ring",
    "a/b",
]


@pytest.mark.parametrize("field", ["system", "model", "profile"])
@pytest.mark.parametrize("name", BAD_NAMES)
def test_a_name_that_is_not_a_name_is_refused_by_every_load(real, tmp_path, field, name):
    path = _put(tmp_path, "job", _crafted(real, **{field: name}))
    good = _put(tmp_path, "good", real[0])
    for strict in (False, True):
        loaded = records.load(tmp_path, strict=strict)
        assert [r["path"] for r in loaded.records] == [str(good.parent)]
        reason = _reasons(loaded)[path]
        assert reason.startswith(f"invalid record: {field}: ") and _one_line(reason), reason
    assert names.name_problem(field, name)


def test_every_installed_plugin_name_is_a_name():
    for kind in ("system", "model", "metric", "claims"):
        for name in registry.discover(kind):  # type: ignore[arg-type]
            assert names.name_problem(kind, name) is None, (kind, name)
    for profile in registry.PROFILES:
        assert names.name_problem("profile", profile) is None


def test_report_writes_nothing_outside_out(real, tmp_path, caplog):
    """Names reach file names only through safe_join: a crafted record with rollouts
    and an absolute or `..` system or profile leaves no file outside --out."""
    sweep, out = tmp_path / "sweep", tmp_path / "out"
    _put(sweep, "good", real[0], real[1])
    for i, (field, name) in enumerate(
        [
            ("system", "../../../escaped"),
            ("system", str(tmp_path / "abs")),
            ("profile", "../../../escaped"),
        ]
    ):
        _put(sweep, f"bad{i}", _crafted(real, **{field: name}), real[1])
    before = {p for p in tmp_path.rglob("*")}
    report = write_report(sweep, out)
    assert len(report.records) == 1 and len(report.unreadable) == 3
    after = {p for p in tmp_path.rglob("*")} - before
    assert after and all(out in p.parents or p == out for p in after), sorted(after)
    assert any(p.name.startswith("spring_") for p in (out / "figures").iterdir())

    # the figures themselves, given such records directly (not through the loader)
    rec = {**real[0], "path": str(sweep / "bad0"), "system": "../../../escaped2"}
    made = make_figures([rec], report.board, out / "figures2")
    assert made == [] and not list(tmp_path.parent.glob("escaped2*"))
    assert "no figures from" in caplog.text


def test_safe_join_refuses_anything_but_plain_components(tmp_path):
    assert safe_join(tmp_path, "spring", "seed0") == tmp_path / "spring" / "seed0"
    for bad in ("..", ".", "", "/etc", "a/b", "a\\b", "x\n", "a\0b"):
        with pytest.raises(UnsafePathError, match="plain file-name component"):
            safe_join(tmp_path, "ok", bad)
    (tmp_path / "link").symlink_to(tmp_path.parent)
    with pytest.raises(UnsafePathError, match="outside"):
        safe_join(tmp_path, "link", "x")


def test_publish_refuses_a_record_dir_outside_results_records(real, tmp_path, monkeypatch):
    monkeypatch.setattr(publish_results, "RECORDS", tmp_path / "records")
    for rec in (
        {**real[0], "system": "../../etc"},
        {**real[0], "model": "/abs"},
        {**real[0], "seed": "0/../.."},
    ):
        with pytest.raises(SystemExit, match="publish: .*(not a system|not a model|seed)"):
            publish_results.record_dir(rec)
    assert publish_results.record_dir(real[0]) == tmp_path / "records/spring/oracle/seed0"
    sweep = tmp_path / "sweep"
    bad = _put(sweep, "job", _crafted(real, system="../../../outside"))
    with pytest.raises(SystemExit, match=f"invalid record.*{bad}|{bad}.*system"):
        publish_results.copy_records([sweep])
    assert not (tmp_path / "records").exists() and not (tmp_path / "outside").exists()


def test_a_plugin_with_a_bad_name_is_refused_with_the_reason(tmp_path, monkeypatch):
    from hnnbench_plugins.models.oracle import Oracle

    monkeypatch.setattr(registry.MODELS, "_registered", {})
    for name in ("../evil", "Oracle2", "a|b", "x" * 65):
        with pytest.raises(ConfigError, match="is not a model name"):
            registry.register("model", name, Oracle)
        assert name not in registry.available("model")
    # an installed entry point of such a name: listed with its reason, never imported
    info = tmp_path / "badname-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: badname\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(
        "[hnnbench.systems]\nBad-System = no_such_module_xyz:Thing\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    registry.refresh()
    try:
        found = registry.discover("system")["Bad-System"]
        assert not found.ok and "is not a system name" in str(found.error)
        assert "No module named" not in str(found.error)
        assert "Bad-System" not in registry.available("system")
        assert registry.discover("system")["spring"].ok
    finally:
        monkeypatch.undo()
        registry.refresh()


# --------------------------------------------------------------------------- markdown


def test_markdown_cells_and_code_spans_are_escaped():
    assert md_cell("a|b") == "a&#124;b"
    assert md_cell("x\ny\r\nz\u2028w") == "x y z w"
    assert md_cell("`rm -rf`") == "&#96;rm -rf&#96;"
    assert "<!--" not in md_cell(MARKER) and "<b" not in md_cell("<b>bold</b>")
    assert md_cell("need <= 2x") == "need <= 2x"  # plain text as it is
    assert md_cell("hnn_torch") == "hnn_torch" and md_cell("1.2e-03 ± 4e-04") == "1.2e-03 ± 4e-04"
    assert md_text("a|b\n<img src=x>") == "a|b &lt;img src=x>"
    assert md_code("x`y\n" + MARKER) == "`x'y \u2039!-- leaderboard:end -->`"
    frame = pd.DataFrame({"model": ["a|b", "x\n| fake | row |", MARKER], "v": ["1", "2", "3"]})
    table = md_table(frame).splitlines()
    assert len(table) == 2 + 3 and all(line.count("|") == 3 for line in table), table
    assert not any("<!--" in line for line in table)


def test_readme_markers_cannot_be_forged_by_content():
    readme = "intro\n<!-- leaderboard:begin -->\nold\n<!-- leaderboard:end -->\nrest\n"
    assert (
        publish_results.replace_block(readme, "leaderboard", "new")
        == "intro\n<!-- leaderboard:begin -->\nnew\n<!-- leaderboard:end -->\nrest\n"
    )
    # a marker quoted inside a line is not a marker
    quoted = readme.replace("old", f"| `{MARKER}` |")
    assert publish_results.replace_block(quoted, "leaderboard", "new").count(MARKER) == 1
    # content left by an older build that forged a marker line: refused, not guessed
    forged = readme.replace("old", MARKER)
    with pytest.raises(SystemExit, match="once, in that order"):
        publish_results.replace_block(forged, "leaderboard", "new")
    # a body holding a marker is never written
    with pytest.raises(SystemExit, match="would contain"):
        publish_results.replace_block(readme, "leaderboard", f"| x |\n{MARKER}")


# --------------------------------------------------------------------------- values


@pytest.mark.parametrize(
    "metric, mean, sem, ok",
    [
        ("energy_mse", -1e-3, 0.0, False),
        ("energy_mse", "-inf", 0.0, False),
        ("energy_mse", "inf", "inf", True),  # diverged: the metric's worst()
        ("energy_mse", None, None, True),  # not applicable
        ("energy_mse", 1e-3, -1.0, False),  # a negative standard error
        ("valid_prediction_time", "inf", 0.0, False),  # a time is finite; worst() is 0
        ("valid_prediction_time", -2.0, 0.0, False),
        ("valid_prediction_time", 0.0, 0.0, True),
        ("rollout_mse", 0.0, 0.0, True),
    ],
)
def test_a_metric_outside_its_declared_domain_is_refused_by_strict_loading(
    real, tmp_path, metric, mean, sem, ok
):
    rec = _crafted(real)
    rec["metrics"][metric] = {"mean": mean, "sem": sem}
    path = _put(tmp_path, "job", rec)
    assert len(records.load(tmp_path).records) == 1  # usable (the report shows it)
    loaded = records.load(tmp_path, strict=True)
    if ok:
        assert loaded.problems == [], loaded.problems
        return
    reason = _reasons(loaded)[path]
    assert reason.startswith(f"invalid record: metrics.{metric}: ") and _one_line(reason)
    findings = check.validate_records(*loaded)
    assert [(f.model, f.current) for f in findings] == [(str(path), reason)]


def test_the_builtin_metrics_declare_their_domain():
    special = {
        "vpt_censored": (0.0, 1.0),  # a share
        "rollout_skill": (-math.inf, 1.0),
    }  # 1 exact, 0 standing still, below: worse
    for metric in registry.metrics():
        assert metric.domain == special.get(metric.name, (0.0, math.inf)), metric.name
    skill = next(m for m in registry.metrics() if m.name == "rollout_skill")
    assert skill.worst() == -math.inf and skill.value_problem(1.5) is not None


@pytest.mark.parametrize(
    "created_at, why",
    [
        ("yesterday", "date-time"),
        ("2026-02-30T00:00:00Z", "date-time"),
        ("2026-11-24 21:00:00+00:00", "date-time"),
        ("2026-11-24T21:00:00", "date-time"),  # no offset
        ("2999-01-01T00:00:00+00:00", "in the future"),
        (20261124, "not of type 'string'"),
    ],
)
def test_a_malformed_or_future_created_at_is_refused(real, tmp_path, created_at, why):
    path = _put(tmp_path, "job", _crafted(real, created_at=created_at))
    reason = _reasons(records.load(tmp_path, strict=True))[path]
    assert "created_at" in reason and why in reason and _one_line(reason), reason
    if why != "in the future":  # the schema's format is enforced on write too
        with pytest.raises(records.InvalidRecord, match="created_at"):
            records.write_record(tmp_path / "w", _crafted(real, created_at=created_at))


def test_the_committed_records_all_load_strictly():
    published = REPO / "results" / "records"
    loaded = records.load(published, strict=True)
    on_disk = len(list(published.rglob("result.json")))
    assert loaded.problems == [] and len(loaded.records) == on_disk > 0


# --------------------------------------------------------------------------- malformed


def test_malformed_records_are_named_and_the_rest_of_report_and_check_goes_on(real, tmp_path):
    sweep = tmp_path / "sweep"
    good = _put(sweep, "good", real[0], real[1])
    bad = {
        "metrics_list": _crafted(real, metrics=[1, 2]),
        "metric_list": _crafted(real, **{"metrics.energy_mse": [1, 2]}),
        "mean_text": _crafted(real, **{"metrics.energy_mse": {"mean": "lots", "sem": 0}}),
        "nested": _crafted(real, config={"a": json.loads("[" * 40 + "]" * 40)}),
        "deep_text": "[" * 100_000 + "]" * 100_000,
        "deep_object": '{"a":' * 50_000 + "1" + "}" * 50_000,
        "history_text": _crafted(real, history={"step": [1, "x"]}),
        "overrides": _crafted(real, overrides=[{"a": 1}]),
        "array": "[1, 2, 3]",
        "binary": b"\xff\xfe\x00garbage",
        "timings": _crafted(real, timings={"fit_s": "soon"}),
    }
    paths = {key: _put(sweep, key, data) for key, data in bad.items()}
    for strict in (False, True):
        loaded = records.load(sweep, strict=strict)
        assert [r["path"] for r in loaded.records] == [str(good.parent)]
        reasons = _reasons(loaded)
        assert set(reasons) == set(paths.values())
        assert all(_one_line(r) for r in reasons.values()), reasons
    reasons = _reasons(records.load(sweep))
    assert "metrics: " in reasons[paths["metrics_list"]]
    assert "metrics.energy_mse: " in reasons[paths["metric_list"]]
    assert "metrics.energy_mse.mean: " in reasons[paths["mean_text"]]
    for key in ("nested", "deep_text", "deep_object"):
        assert "nested deeper than 32 levels" in reasons[paths[key]], key
    report = write_report(sweep, tmp_path / "out")
    assert len(report.records) == 1 and len(report.unreadable) == len(bad)
    recs, problems = records.load(sweep, strict=True)
    findings = check.validate_records(recs, problems)
    assert {f.model for f in findings} == {str(p) for p in paths.values()}


def test_a_large_record_is_refused_by_size_at_once_and_a_long_history_is_fast(real, tmp_path):
    big = _crafted(real, history={"step": list(range(700_000))})
    path = _put(tmp_path / "big", "job", big)
    assert path.stat().st_size > 4_000_000
    start = time.perf_counter()
    reason = _reasons(records.load(tmp_path / "big", strict=True))[path]
    assert time.perf_counter() - start < 2.0
    assert "over the limit of 2097152" in reason and _one_line(reason)

    n = 55_000
    # A long history that agrees with the record's steps (issue 48: the log is checked
    # against them), without a selection to check against it.
    long = _crafted(
        real,
        steps=n,
        history={
            "step": list(range(1, n + 1)),
            "train_loss": [0.1 + i * 1e-7 for i in range(n)],
            "test_loss": [0.2 + i * 1e-7 for i in range(n)],
        },
    )
    long.pop("selection", None)
    path = _put(tmp_path / "long", "job", long)
    assert 1_500_000 < path.stat().st_size <= records.MAX_RECORD_BYTES
    start = time.perf_counter()
    loaded = records.load(tmp_path / "long", strict=True)
    elapsed = time.perf_counter() - start
    assert loaded.problems == [] and len(loaded.records) == 1
    assert elapsed < 1.0, elapsed


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_a_symlink_to_an_endless_file_or_a_pipe_is_not_read(real, tmp_path):
    good = _put(tmp_path, "good", real[0])
    (tmp_path / "zero").mkdir()
    (tmp_path / "zero" / records.RECORD_NAME).symlink_to("/dev/zero")
    (tmp_path / "inside").mkdir()
    (tmp_path / "inside" / "real.json").write_text(json.dumps(real[0]))
    (tmp_path / "inside" / records.RECORD_NAME).symlink_to(tmp_path / "inside" / "real.json")
    (tmp_path / "fifo").mkdir()
    os.mkfifo(tmp_path / "fifo" / records.RECORD_NAME)
    start = time.perf_counter()
    loaded = records.load(tmp_path, strict=True)
    assert time.perf_counter() - start < 5.0
    assert [r["path"] for r in loaded.records] == [str(good.parent)]
    reasons = _reasons(loaded)
    assert "symbolic link" in reasons[tmp_path / "zero" / records.RECORD_NAME]
    assert "symbolic link" in reasons[tmp_path / "inside" / records.RECORD_NAME]
    assert "not a regular file" in reasons[tmp_path / "fifo" / records.RECORD_NAME]


def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def test_a_rollout_is_read_bounded(real, tmp_path, monkeypatch, caplog):
    # a decompression bomb: 16 MB of zeros in a few KB, against a limit of 8 MB
    bomb = tmp_path / "bomb.npz"
    bomb.write_bytes(_npz(states_true=np.zeros(2_000_000)))
    assert bomb.stat().st_size < 100_000
    with pytest.raises(records.UnsafeFile, match="decompressed, over the limit"):
        records.load_arrays(bomb, limit=8_000_000)
    # a header that declares far more data than its member holds
    lying = tmp_path / "lying.npz"
    with zipfile.ZipFile(lying, "w") as zf:
        buf = io.BytesIO()
        np.lib.format.write_array(buf, np.zeros(4))
        raw = buf.getvalue().replace(b"(4,)", b"(4000000000000,)".ljust(4))
        zf.writestr("t.npy", raw)
    with pytest.raises(records.UnsafeFile, match="declares"):
        records.load_arrays(lying)
    # objects are never unpickled
    objects = tmp_path / "objects.npz"
    objects.write_bytes(_npz(t=np.array([{"a": 1}], dtype=object)))
    with pytest.raises(records.UnsafeFile, match="holds objects"):
        records.load_arrays(objects)
    # the report: a bomb beside a record draws no figure, and the report goes on
    monkeypatch.setattr(store, "MAX_ROLLOUT_BYTES", 8_000_000)
    sweep = tmp_path / "sweep"
    _put(sweep, "job", real[0], bomb.read_bytes())
    report = write_report(sweep, tmp_path / "out")
    assert len(report.records) == 1 and not [m for m in report.figures if m.label == "spring"]
    assert "cannot read" in caplog.text and "over the limit" in caplog.text
    # a real rollout still reads
    (tmp_path / "real.npz").write_bytes(real[1])
    assert "states_true" in records.load_arrays(tmp_path / "real.npz")


# --------------------------------------------------------------------------- fuzz

_json = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**6), 10**6)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=20),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=10), children, max_size=4)
    ),
    max_leaves=20,
)
_FIELDS = [f.name for f in records.FIELDS]


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_fuzz_the_loader_never_raises_and_names_every_file_left_out(real, tmp_path_factory, data):
    root = tmp_path_factory.mktemp("fuzz")
    written = []
    for i in range(3):
        kind = data.draw(st.sampled_from(["bytes", "json", "mutated"]))
        if kind == "bytes":
            content = data.draw(st.binary(max_size=200))
        elif kind == "json":
            content = json.dumps(data.draw(_json)).encode()
        else:  # a real record with some fields replaced, added or removed
            rec = copy.deepcopy(real[0])
            for _ in range(data.draw(st.integers(1, 3))):
                key = data.draw(st.sampled_from(_FIELDS) | st.text(max_size=8))
                if data.draw(st.booleans()):
                    rec.pop(key, None)
                else:
                    rec[key] = data.draw(_json)
            content = json.dumps(rec).encode()
        written.append(_put(root, f"job{i}", content))
    for strict in (False, True):
        loaded = records.load(root, strict=strict)
        found = [Path(r["path"]) / records.RECORD_NAME for r in loaded.records]
        named = [p.path for p in loaded.problems]
        assert sorted(found + named) == sorted(written)
        assert all(p.reason and _one_line(p.reason) for p in loaded.problems)
        if strict:
            for rec in loaded.records:
                assert records.strict_problems(rec) == []


def test_a_value_outside_its_domain_is_never_marked_best(tmp_path):
    """The report (not strict) shows such a record, but never marks it best or tied."""
    from hnnbench._results.families import families
    from hnnbench._results.leaderboard import records_frame

    for model, value in (("mlp_torch", -5.0), ("hnn_torch", 2e-3), ("dhnn_torch", 1e-2)):
        for seed in range(10):  # the fewest seeds that separate: 6
            write_run(tmp_path, "spring", model, seed, metrics={"energy_mse": value}, rollout=False)
    board = families(records_frame(records.load(tmp_path).records)).board.set_index("family")
    assert board["energy_mse_mark"].to_dict() == {"mlp": "", "hnn": "best", "dhnn": ""}


@pytest.mark.parametrize("field", ["history", "metrics", "selection", "timings", "config", "data"])
@pytest.mark.parametrize("key", ["\n", "a\nb", "\r", "\x1b[31m", "\u2028"])
def test_a_key_that_breaks_lines_is_named_in_one_line(real, tmp_path, field, key):
    """A record's key holding a line break or a control character is named escaped:
    the loader's reason stays one line (a case the fuzz test above found)."""
    rec = copy.deepcopy(real[0])
    rec[field] = {key: None}
    _put(tmp_path, "job", rec)
    for strict in (False, True):
        loaded = records.load(tmp_path, strict=strict)
        for problem in loaded.problems:
            assert _one_line(problem.reason) and problem.reason.isprintable(), problem.reason


@pytest.mark.parametrize("key", ["a\nb", "\x1b[31m"])
def test_a_history_key_is_named_escaped_by_the_consistency_rules(real, tmp_path, key):
    """A history series of the wrong length under a key that breaks lines: the
    consistency rule names it escaped, in ``strict_problems`` too."""
    rec = copy.deepcopy(real[0])
    rec["history"] = {"step": [1, 2], "train_loss": [0.5, 0.25], key: [0.0, 0.0, 0.0]}
    problems = records.strict_problems(rec)
    assert problems and all(_one_line(p) and p.isprintable() for p in problems), problems
