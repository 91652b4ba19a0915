"""The README and the user guide stay true.

* The README's two fresh-machine commands: CI runs the second, this file the first's job.
* The README fits on a screen (≤ 300 lines) and leads to every page of the guide (docs/guide).
* Every relative link of the README and the guide resolves, anchors included.
* Every command they show names a real command, real options and real files, and the quick
  ones (simulate, calibrate, diagnose, export, apply, convert, plan) run, in order, in a
  temporary folder, and write what they say.
* The modules, attributes and files they name (`wheelcal.x.y`, `estimate/joint/fit.py`) exist.
"""

import dataclasses
import functools
import importlib
import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from truth_bound import SENSOR_NAMES, scenario_noise
from wheelcal.batch.pipeline import load_pipeline
from wheelcal.cli.main import build_parser, main
from wheelcal.closedloop.sensor_fit import sensor_crlb
from wheelcal.estimate.joint.crlb import cramer_rao_bound
from wheelcal.io import read_recording
from wheelcal.simulate import NoiseSpec, Quantiser, preset, table2
from wheelcal.simulate.session import simulate_session

ROOT = Path(__file__).resolve().parents[1]


def _commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```sh\n(.*?)\n```", text, flags=re.S)
    return [b.strip() for b in blocks[:2]]


def test_readme_opens_with_exactly_two_commands():
    text = (ROOT / "README.md").read_text()
    head = text.split("\n\n", 3)
    assert head[0].startswith("# wheelcal")
    assert head[1].startswith("```sh") and head[2].startswith("```sh")
    assert all("\n" not in c for c in _commands())


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1].strip()
    assert ci == _commands()[1]
    assert "pytest" in ci and "[test]" in ci


def _truth_sessions(pipeline):
    """The pipeline's simulated sessions, rebuilt with their truth (the same random streams)."""
    spec = pipeline.simulate
    sessions = []
    for i in range(spec.count):
        rng = np.random.default_rng([spec.seed, i])
        scenario = preset(spec.preset, rng=rng)
        scenario = dataclasses.replace(
            scenario, noise=NoiseSpec(spec.noise_mps2, bandwidth_hz=spec.bandwidth_hz)
        )
        if spec.quantise:
            scenario = dataclasses.replace(scenario, quantiser=Quantiser())
        sessions.append(simulate_session(scenario, rng))
    return sessions


def _fitted_times(session, w0: float, w1: float) -> np.ndarray:
    """The window's sample times, less those the truth puts within 4 σ_n of a clipping rail.

    The session fit leaves out the samples its model puts near a rail (the reader drops
    the clipped ones); selecting by the truth instead differs by a handful of samples.
    """
    rec, scenario = session.recording, session.scenario
    lo, hi = scenario.quantiser.limits_mps2
    margin = 4 * np.max(scenario.noise.std_mps2)
    clean = session.clean_mps2
    near = np.any((clean >= hi - margin) | (clean <= lo + margin), axis=1)
    inside = (rec.time_s >= w0 - 1e-9) & (rec.time_s <= w1 + 1e-9)
    return rec.time_s[inside & ~near]


def test_main_command_runs_the_bundled_pipeline(tmp_path, monkeypatch, capsys):
    """README's first command's job, in a temp dir: the files it lists and the truth recovered."""
    main_cmd = _commands()[0]
    match = re.search(r"wheelcal batch (\S+\.toml)", main_cmd)
    assert match, main_cmd
    pipeline = load_pipeline(ROOT / match.group(1))
    assert pipeline.simulate is not None and pipeline.simulate.count == 10
    assert pipeline.rerun
    monkeypatch.chdir(tmp_path)  # the pipeline's relative output lands here
    assert main(["batch", str(ROOT / match.group(1)), "--workers", "2"]) == 0
    capsys.readouterr()
    out = tmp_path / "out" / "table2-repeatability"
    # Every file the README lists.
    sensor_file = out / "sensors" / "mpu9250-A.calibration.json"
    for name in ("report.md", "overview.png", "report.json", "sessions.csv", "batch.rrd"):
        assert (out / name).stat().st_size > 0, name
    cals = sorted(out.glob("*.calibration.json"))
    assert len(cals) == 10 and len(list(out.glob("*.rrd"))) == 11
    # report.md opens with the calibration to apply.
    assert (out / "report.md").read_text().split("\n\n")[2].startswith("## Apply this")
    report = json.loads((out / "report.json").read_text())
    assert report["sessions"] == 10 and report["failed"] == []
    # The numbers: each session and the pooled sensor against the CRLB at the simulator's truth,
    # over the windows the batch fitted (the true noise: coloured by the 41 Hz low-pass).
    sessions = _truth_sessions(pipeline)
    states, times, noises = [], [], []
    for session, path in zip(sessions, cals, strict=True):
        cal = json.loads(path.read_text())
        w0, w1 = cal["source"]["window_s"]
        centre = 0.5 * (w0 + w1)
        truth = session.truth.with_changes(
            spin=session.truth.spin.shifted(centre - session.centre_s)
        )
        t = _fitted_times(session, w0, w1) - centre
        assert abs(t.size - cal["source"]["samples"]) < 0.01 * t.size, (path.name, t.size)
        noise = scenario_noise(session.scenario)
        bound = cramer_rao_bound(truth, t, noise)
        for name in SENSOR_NAMES:
            i = bound.names.index(name)
            z = (cal["parameters"][name]["value"] - bound.values[i]) / bound.std[i]
            assert abs(z) < 4.5, (path.name, name, z)
        states.append(truth)
        times.append(t)
        noises.append(noise)
    pooled_bound = sensor_crlb(states, times, noises)
    deliverable = json.loads(sensor_file.read_text())
    truth = sessions[0].truth.sensor
    values = {
        **{f"gain_{a}": v for a, v in zip("xyz", deliverable["sensor"]["gain"], strict=True)},
        **{
            f"offset_{a}_mps2": v
            for a, v in zip("xyz", deliverable["sensor"]["offset_mps2"], strict=True)
        },
    }
    true = {
        **{f"gain_{a}": v for a, v in zip("xyz", truth.gain, strict=True)},
        **{f"offset_{a}_mps2": v for a, v in zip("xyz", truth.offset_mps2, strict=True)},
    }
    for name in SENSOR_NAMES:
        z = (values[name] - true[name]) / pooled_bound[name]
        assert abs(z) < 4.0, (name, values[name], true[name], pooled_bound[name])


# --- The README and the user guide: short, linked, every command shown runnable -------------

GUIDE = ROOT / "docs" / "guide"
#: Every page a reader can reach: the README, the guide and the study's own pages.
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
#: Commands quick enough to run for real, in a temporary folder.
QUICK = {"simulate", "calibrate", "diagnose", "export", "apply", "convert", "plan"}
#: Folders of the project whose files a command may name.
PROJECT_DIRS = ("pipelines/", "docs/", "benchmarks/", "tools/", "tests/", "src/")


def _page_id(path: Path) -> str:
    return str(path.relative_to(ROOT))


def _fenced(text: str, lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", text, flags=re.S | re.M)


def _prose(text: str) -> str:
    """The text without fenced blocks and inline code (links there are not links)."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def _code_spans(text: str) -> list[str]:
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return [s.replace("\\|", "|") for s in re.findall(r"`([^`\n]+)`", text)]


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to dashes."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"^```.*?^```", "", path.read_text(), flags=re.S | re.M)
    seen: dict[str, int] = {}
    anchors = set()
    for heading in re.findall(r"^#{1,6} +(.+?) *#*$", text, flags=re.M):
        slug = _slug(heading)
        n = seen.get(slug, 0)
        anchors.add(slug if n == 0 else f"{slug}-{n}")
        seen[slug] = n + 1
    return anchors


def _links(path: Path) -> list[str]:
    return re.findall(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", _prose(path.read_text()))


def test_readme_fits_on_a_screen_and_points_to_the_guide():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 300, len(lines)
    index = GUIDE / "README.md"
    links = {(ROOT / link.split("#")[0]).resolve() for link in _links(ROOT / "README.md")}
    assert index.resolve() in links
    # Every page of the guide is listed in its index and in the README's contents.
    listed = {(GUIDE / link.split("#")[0]).resolve() for link in _links(index)}
    for page in GUIDE.glob("*.md"):
        if page != index:
            assert page.resolve() in listed, f"{page.name} is not in the guide's index"
            assert page.resolve() in links, f"{page.name} is not in the README's contents"


def test_every_relative_link_resolves():
    broken = []
    for page in PAGES:
        for link in _links(page):
            if re.match(r"[a-z]+:", link):  # https:, mailto:
                continue
            target, _, anchor = link.partition("#")
            file = (page.parent / target).resolve() if target else page
            if not file.is_relative_to(ROOT) or not file.exists():
                broken.append(f"{_page_id(page)}: {link} (no such file in the project)")
            elif anchor and file.suffix == ".md" and anchor not in _anchors(file):
                broken.append(f"{_page_id(page)}: {link} (no heading #{anchor})")
    assert not broken, "\n".join(broken)


def test_nothing_points_outside_the_project():
    for page in PAGES:
        text = page.read_text()
        assert "../shared" not in text and "/work/" not in text, _page_id(page)


def _subparsers() -> dict:
    (action,) = [a for a in build_parser()._actions if a.choices and "calibrate" in a.choices]
    return action.choices


def _script_options() -> set[str]:
    """The long options the project's scripts define (benchmarks, tools, docs)."""
    options = set()
    for folder in ("benchmarks", "tools", "docs"):
        for script in (ROOT / folder).rglob("*.py"):
            options |= set(re.findall(r"[\"'](--[a-z][a-z0-9-]*)[\"']", script.read_text()))
    return options


def _shown_commands(page: Path) -> tuple[list[str], list[str]]:
    """(lines of the page's ``sh`` blocks, inline code spans that are commands)."""
    blocks = _fenced(page.read_text(), "sh")
    if page == ROOT / "README.md":
        blocks = blocks[2:]  # the two fresh-machine commands: tested above and by CI
    lines = [re.sub(r"\s+#.*$", "", ln).strip() for b in blocks for ln in b.splitlines()]
    lines = [ln for ln in lines if ln and not ln.startswith("#")]
    spans = [s for s in _code_spans(page.read_text()) if re.search(r"\bwheelcal \w|\.py\b", s)]
    return lines, [s for s in spans if re.match(r"(\S+=\S+ )*(wheelcal|python|pytest) ", s)]


def _is_synopsis(command: str) -> bool:
    return bool(re.search(r"[\[\]…|]|\.\.\.|\b[A-Z]+\.(mcap|json|toml|csv)\b|DIR\b", command))


def _check_command(command: str, parsers: dict, script_options: set[str]) -> str | None:
    """Why a shown command would not run (None if it would), without running it."""
    words = command.split()
    while words and "=" in words[0] and not words[0].startswith("-"):
        words = words[1:]  # PYTHONPATH=src:tests ...
    if not words:
        return "empty command"
    if words[0].endswith("wheelcal"):
        if len(words) < 2 or words[1] not in parsers:
            return f"no such command: {command}"
        sub = parsers[words[1]]
        known = {o for a in sub._actions for o in a.option_strings}
        unknown = [f for f in re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", command) if f not in known]
        if unknown:
            return f"wheelcal {words[1]} has no option {', '.join(unknown)}: {command}"
        if len(words) > 2 and not _is_synopsis(command):  # `wheelcal batch` is only a name
            try:
                build_parser().parse_args(shlex.split(command)[1:])
            except SystemExit as exc:  # --help exits 0; a bad command line exits 2
                if exc.code != 0:
                    return f"does not parse: {command}"
    elif words[0] in ("python", "pytest") or words[0].endswith("/python"):
        paths = [w for w in words if w.endswith(".py") or w.startswith(PROJECT_DIRS)]
        for word in paths:
            if not (ROOT / word.strip("[],;:")).exists():
                return f"no such file {word}: {command}"
        scripts = [ROOT / w for w in paths if w.endswith(".py") and w.startswith(PROJECT_DIRS)]
        flags = re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", command)
        if scripts and scripts[0].parent.name != "tests":
            text = scripts[0].read_text()
            missing = [f for f in flags if f'"{f}"' not in text and f"'{f}'" not in text]
            if missing:
                return f"{scripts[0].name} has no option {', '.join(missing)}: {command}"
        elif flags and not set(flags) <= script_options:
            return f"unknown options {flags}: {command}"
    for word in words:
        word = word.strip("[],;:")
        if word.startswith(PROJECT_DIRS) and not (ROOT / word).exists():
            return f"no such file {word}: {command}"
    return None


@pytest.mark.parametrize("page", PAGES, ids=_page_id)
def test_every_command_shown_parses(page):
    """Each command a page shows names a real command, real options and real files."""
    parsers, script_options = _subparsers(), _script_options()
    lines, spans = _shown_commands(page)
    problems = [p for c in lines + spans if (p := _check_command(c, parsers, script_options))]
    # An option named on its own (`--radius`) exists somewhere: a command's or a script's.
    every_option = {o for a in build_parser()._actions for o in a.option_strings}
    every_option |= {o for sub in parsers.values() for a in sub._actions for o in a.option_strings}
    for span in _code_spans(page.read_text()):
        for flag in re.findall(r"^--[a-z][a-z0-9-]*|(?<=/)--[a-z][a-z0-9-]*", span):
            if flag not in every_option | script_options:
                problems.append(f"no command or script has the option {flag} (`{span}`)")
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("command", sorted(_subparsers()))
def test_every_command_has_help(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: wheelcal {command}")


G = 9.80665


@functools.cache
def _field_recording():
    """The recording the guide's CSV examples stand for: a Table II session at 200 Hz."""
    rng = np.random.default_rng(21)
    return simulate_session(table2(rng=rng), np.random.default_rng(22)).recording


def _write_arduino_csv(path: Path) -> None:
    """``millis,ax,ay,az`` in raw counts at ±8 g (4096 per g), as an Arduino sketch prints."""
    rec = _field_recording()
    t = np.round(rec.time_s * 1e3).astype(np.int64)
    raw = np.clip(np.round(rec.accel_mps2 / G * 4096), -32768, 32767).astype(np.int64)
    rows = [f"{a},{x},{y},{z}" for a, (x, y, z) in zip(t.tolist(), raw.tolist(), strict=True)]
    path.write_text("millis,ax,ay,az\r\n" + "\r\n".join(rows) + "\r\n")


def _write_phyphox_csv(path: Path) -> None:
    """phyphox's export: quoted headers with units, numbers in scientific notation."""
    rec = _field_recording()
    head = ['"Time (s)"'] + [f'"Acceleration {a} (m/s^2)"' for a in "xyz"]
    rows = [
        ",".join(f"{v:.9E}" for v in (t, *a))
        for t, a in zip(rec.time_s.tolist(), rec.accel_mps2.tolist(), strict=True)
    ]
    path.write_text(",".join(head) + "\n" + "\n".join(rows) + "\n")


#: Input files the guide's examples assume the reader has, made here.
FIXTURES = {"arduino.csv": _write_arduino_csv, "phyphox.csv": _write_phyphox_csv}


def _runnable(page: Path) -> list[list[str]]:
    lines, _ = _shown_commands(page)
    commands = [shlex.split(ln) for ln in lines if ln.startswith("wheelcal ")]
    return [c for c in commands if c[1] in QUICK]


RUNNABLE = [p for p in PAGES if _runnable(p)]


def _option(args: list[str], name: str) -> str | None:
    return args[args.index(name) + 1] if name in args else None


def _positionals(args: list[str], parser) -> list[str]:
    """The positional arguments of a command line (options and their values left out)."""
    out, skip = [], 0
    for word in args:
        if skip:
            skip -= 1
        elif word.startswith("--"):
            action = next(a for a in parser._actions if word in a.option_strings)
            skip = action.nargs if isinstance(action.nargs, int) else 1  # store_true: 0
        else:
            out.append(word)
    return out


def _check_against_truth(cal_path: Path, truth_path: Path) -> None:
    cal, truth = json.loads(cal_path.read_text()), json.loads(truth_path.read_text())
    for key, std in (("gain", "gain_std"), ("offset_mps2", "offset_std_mps2")):
        # a value the recording cannot determine is null (with its reason): not compared
        value = np.array([np.nan if v is None else v for v in cal["sensor"][key]])
        sigma = np.array([np.nan if v is None else v for v in cal["sensor"][std]])
        z = (value - truth["sensor"][key]) / sigma
        assert np.all(np.abs(z[np.isfinite(z)]) < 5), (cal_path.name, key, z)


def _check_calibrations(command, args, recordings, truths) -> None:
    """`calibrate`/`diagnose`: each recording's files, and the truth where it is known."""
    out_dir = Path(_option(args, "--out"))
    for name in recordings:
        stem = Path(name).stem
        assert (out_dir / f"{stem}.calibration.json").stat().st_size > 0, (out_dir, stem)
        if command == "diagnose":
            assert (out_dir / f"{stem}.diagnosis.json").stat().st_size > 0
        if "--rrd" in args:
            assert (out_dir / f"{stem}.rrd").stat().st_size > 0
        if name in truths:
            _check_against_truth(out_dir / f"{stem}.calibration.json", truths[name])


def _check_written(command, args, positionals, printed, truths) -> None:
    """What a command that ran says it writes is there, and holds what it should."""
    if command == "simulate":
        assert Path(positionals[-1]).stat().st_size > 0
        if _option(args, "--truth"):
            truths[positionals[-1]] = Path(_option(args, "--truth"))
    elif command == "convert":
        back = read_recording(positionals[-1], info_overrides={"radius_m": 0.28})
        rows = len(Path(positionals[0]).read_text().splitlines()) - 1
        assert abs(back.time_s.size - rows) <= 0.01 * rows, (back.time_s.size, rows)
    elif command == "apply":
        with open(positionals[-1], "rb") as f:
            topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
        assert any(t.endswith("/calibrated") for t in topics), topics
    elif command in ("calibrate", "diagnose"):
        _check_calibrations(command, args, positionals, truths)
    elif command == "export":
        written = _option(args, "--out")
        text = Path(written).read_text() if written else printed
        assert "bias" in text.lower(), text[:200]
    elif command == "plan":
        assert "offset" in (json.dumps(json.loads(printed)) if "--json" in args else printed)


@pytest.mark.parametrize("page", RUNNABLE, ids=_page_id)
def test_the_quick_commands_shown_run(page, tmp_path, monkeypatch, capsys):
    """A page's simulate/calibrate/export/convert/... commands, run in order in a temp folder.

    Each must exit 0 and write what it names; a calibration of a simulated recording whose
    truth was written (``--truth``) must recover it within 5 σ.
    """
    monkeypatch.chdir(tmp_path)
    parsers = _subparsers()
    truths: dict[str, Path] = {}
    for words in _runnable(page):
        command, args = words[1], words[2:]
        positionals = _positionals(args, parsers[command])
        # The files a command reads: every positional but the output of those that write one.
        inputs = positionals[:-1] if command in ("simulate", "convert", "apply") else positionals
        for name in inputs:
            if not Path(name).exists() and name in FIXTURES:
                FIXTURES[name](tmp_path / name)
            assert Path(name).exists(), f"{_page_id(page)}: `{' '.join(words)}` needs {name}"
        status = main([command, *args])
        printed = capsys.readouterr().out
        assert status == 0, f"{_page_id(page)}: `{' '.join(words)}` exited {status}"
        _check_written(command, args, positionals, printed, truths)


def test_the_pipeline_file_shown_loads_and_every_key_is_documented(tmp_path):
    """The guide's example pipeline is a valid one, and its key list misses no key."""
    from wheelcal.batch import pipeline as pipeline_module

    page = GUIDE / "batch.md"
    (example,) = _fenced(page.read_text(), "toml")
    path = tmp_path / "example.toml"
    path.write_text(example)
    loaded = load_pipeline(path)
    assert loaded.options.gates.gain_tolerance == 0.03 and loaded.globs
    documented = set(re.findall(r"`([a-z_0-9]+)`", page.read_text()))
    sections = pipeline_module._SECTIONS
    missing = {f"[{s}] {k}" for s, keys in sections.items() for k in keys if k not in documented}
    assert not missing, f"{_page_id(page)} does not list {sorted(missing)}"
    assert all(f"`[{s}]`" in page.read_text() for s in sections)


#: Names in backticks that look like Python but name a JSON schema or a metadata record.
NOT_PYTHON = {"wheelcal.AccelBatch", "wheelcal.SampleFlag", "wheelcal.apply", "wheelcal.output"}


def _resolves(dotted: str) -> bool:
    """A module, or an attribute chain under the longest importable module."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False


def _source_file(name: str) -> bool:
    """A file named in the text: from the project's root, under src/ or src/wheelcal, or a
    bare script name in one of the script folders."""
    bases = (ROOT, ROOT / "src", ROOT / "src" / "wheelcal")
    if any((base / name).is_file() for base in bases):
        return True
    folders = ("benchmarks", "tools", "docs", "tests")
    return "/" not in name and any(any((ROOT / f).rglob(name)) for f in folders)


@pytest.mark.parametrize("page", PAGES, ids=_page_id)
def test_the_modules_and_files_named_exist(page):
    """`wheelcal.x.y` names and `.py` files the text gives exist in the code as it is."""
    missing = []
    for span in _code_spans(page.read_text()):
        for name in re.findall(r"(?<![\w.])wheelcal(?:\.\w+)+(?![\w/])", span):
            if name not in NOT_PYTHON and not _resolves(name):
                missing.append(f"`{name}` (in `{span}`)")
        if re.fullmatch(r"[\w./-]+\.py", span) and not _source_file(span):
            missing.append(f"file `{span}`")
    assert not missing, f"{_page_id(page)} names what does not exist: " + ", ".join(missing)
