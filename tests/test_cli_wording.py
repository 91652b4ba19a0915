"""What the command line says is true (issue 39, "The command line"): each item as filed.

* ``simulate --preset bogus`` lists every preset; a field preset takes ``--noise`` and
  refuses the bench's options instead of ignoring them;
* a unit refused at rest names who stated it (``--accel-unit``, not "the file");
* a radius typed ×0.1 is refused as the radius (``gain_range``) when the rests read g;
* the API's refusal speaks the API's keywords (``radius_m=``, not ``--radius``);
* ``wheelcal --help`` points at the guide's pages, and every option has a help text;
* ``plan`` prints no round-off for a zero;
* the README has no sentence cut off, its speed line says what it measures, and
  ``development.md``'s test count is the suite's;
* a rosbag2 compressed file by file is read (zstandard), not sent to ``ros2 bag decompress``.
"""

from __future__ import annotations

import argparse
import ast
import re
from pathlib import Path

import numpy as np
import pytest

import wheelcal
from wheelcal.cli.main import build_parser, main
from wheelcal.io import read_recording

ROOT = Path(__file__).resolve().parents[1]
PRESETS = ("table1", "table2", "car", "robot", "wheelchair", "stand")


@pytest.fixture(scope="module")
def session_file(tmp_path_factory):
    """A default simulated session (rests before and after the spin), ROS 2 Imu."""
    path = tmp_path_factory.mktemp("wording") / "spin.mcap"
    assert main(["simulate", str(path), "--seed", "11"]) == 0
    return path


def test_an_unknown_preset_lists_every_preset(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "x.mcap"), "--preset", "bogus"]) == 2
    said = capsys.readouterr().err
    assert "bogus" in said
    listed = set(re.findall(r"[a-z0-9]+", said.split("choose from", 1)[1]))
    assert set(PRESETS) <= listed, listed


def test_a_field_preset_takes_the_noise_it_is_given(tmp_path):
    default, noisy = tmp_path / "car.mcap", tmp_path / "car_noisy.mcap"
    assert main(["simulate", str(default), "--preset", "car", "--seed", "3"]) == 0
    argv = ["simulate", str(noisy), "--preset", "car", "--seed", "3", "--noise", "0.5"]
    assert main(argv) == 0
    a, b = read_recording(default), read_recording(noisy)
    assert a.samples == b.samples
    # The same draws, scaled: the difference is (0.5 − σ₀)·e with σ₀ ≤ 0.02 m/s².
    spread = np.std(b.accel_mps2 - a.accel_mps2, axis=0)
    assert np.all((spread > 0.45) & (spread < 0.52)), spread


@pytest.mark.parametrize("option", [["--reverse"], ["--quantise"], ["--temperature"]])
def test_a_field_preset_refuses_the_bench_options(tmp_path, capsys, option):
    path = tmp_path / "car.mcap"
    assert main(["simulate", str(path), "--preset", "car", *option]) == 2
    said = capsys.readouterr().err
    assert option[0] in said and "table1" in said
    assert not path.exists()


def test_a_unit_given_by_the_option_is_named_as_the_option(session_file, tmp_path, capsys):
    assert main(["calibrate", str(session_file), "--out", str(tmp_path), "--accel-unit", "g"]) == 1
    said = capsys.readouterr().err
    assert "--accel-unit g" in said and "says g" in said
    assert "the file says" not in said and "driver" not in said
    assert "leave --accel-unit out" in said


def test_a_radius_typed_a_tenth_is_the_radius_when_the_rests_read_g(session_file, tmp_path, capsys):
    assert main(["calibrate", str(session_file), "--out", str(tmp_path), "--radius", "0.028"]) == 1
    said = capsys.readouterr().err
    assert "refused (gain_range)" in said
    assert "labelled" not in said  # the unit is not suspected: the rests read 9.8 m/s²
    assert said.index("0.028 m given") < said.index("rests read")


def test_the_api_refusal_names_keywords(session_file):
    for radius in (0.028, 280.0):
        with pytest.raises(wheelcal.CalibrationRefused) as caught:
            wheelcal.calibrate(session_file, radius_m=radius)
        refusal = caught.value
        assert "radius_m=" in refusal.fix and "--radius" not in refusal.fix
        assert "--" not in refusal.reason


def test_the_api_words_cover_the_options_the_gates_name():
    from wheelcal.api import api_words

    text = "state the unit (--accel-unit m/s^2, or …), or give --radius; see --start-s/--end-s"
    said = api_words(text)
    assert said == (
        "state the unit (accel_unit='m/s^2', or …), or give radius_m=; see start_s=/end_s="
    )


def test_help_points_at_the_guide(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    said = " ".join(capsys.readouterr().out.split())
    pages = re.findall(r"docs/guide/[a-z-]+\.md", said)
    assert "docs/guide/outputs.md" in pages
    assert all((ROOT / page).is_file() for page in pages)
    assert "README.md" not in said


def test_every_option_has_a_help_text():
    parser = build_parser()
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    missing = [
        f"{name} {action.option_strings[0]}"
        for name, command in commands.choices.items()
        for action in command._actions
        if action.option_strings and not action.help
    ]
    assert missing == []


@pytest.mark.parametrize("geometry", ["tilt", "vertical"])
def test_plan_prints_no_round_off(capsys, geometry):
    assert main(["plan", "--geometry", geometry, "--no-tradeoffs"]) == 0
    said = capsys.readouterr().out
    tiny = [m for m in re.findall(r"\d(?:\.\d+)?e-(\d+)", said) if int(m) >= 13]
    assert tiny == [], said


def _paragraphs(text: str) -> list[str]:
    """A markdown file's paragraphs and list items, outside code blocks and tables."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    out = []
    for block in re.split(r"\n\s*\n", text):
        item: list[str] = []
        for line in block.strip().splitlines():
            if re.match(r"\s*(?:[-*]|\d+\.) ", line) and item:
                out.append(" ".join(item))
                item = []
            item.append(line.strip())
        out.append(" ".join(item))
    return [p for p in out if p and not p.startswith(("#", "|", "![", "<", "[User guide]"))]


def test_no_sentence_of_the_readme_or_the_guide_is_cut_off():
    files = [ROOT / "README.md", *sorted((ROOT / "docs" / "guide").glob("*.md"))]
    cut = [
        f"{f.name}: …{p[-60:]}"
        for f in files
        for p in _paragraphs(f.read_text(encoding="utf-8"))
        if not re.search(r"(?:[.:;!?)\]`*>…])$", p)
    ]
    assert cut == []


def test_the_readme_speed_line_says_what_it_measures():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    (paragraph,) = [p for p in text.split("\n\n") if "14 ms" in p or "14–15 ms" in p]
    words = " ".join(paragraph.split())
    # the figure is Table I's white-noise spin without rests, not a user's recording …
    assert "white noise" in words and "without rests" in words
    # … and a recording as a batch calibrates it gets its own figure, per session
    assert re.search(r"per session", words) and "rests, push and stop" in words


def _test_functions() -> int:
    count = 0
    for path in (ROOT / "tests").glob("test_*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        count += sum(
            isinstance(node, ast.FunctionDef) and node.name.startswith("test")
            for node in ast.walk(tree)
        )
    return count


def test_development_page_states_the_suites_size():
    text = " ".join((ROOT / "docs/guide/development.md").read_text(encoding="utf-8").split())
    stated = [int(n.replace(",", "")) for n in re.findall(r"([\d,]+) test functions", text)]
    assert stated, "development.md should say how many test functions there are"
    actual = _test_functions()
    assert all(abs(n - actual) <= 0.15 * actual for n in stated), (stated, actual)


def test_a_rosbag2_compressed_file_by_file_is_read(tmp_path, monkeypatch):
    import tempfile

    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from rosbags.typesys import Stores, get_typestore

    from robot_logs import imu_messages, write_db3

    rng = np.random.default_rng(5)
    time_ns = 1_700_000_000_000_000_000 + np.arange(2400) * 5_000_000
    accel = np.array([0.0, 0.0, 9.81]) + 0.05 * rng.standard_normal((2400, 3))
    messages = imu_messages(time_ns, accel)
    plain = write_db3(tmp_path / "plain", time_ns, messages)
    folder = tmp_path / "by_file"
    writer = Writer(folder, version=8)
    writer.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
    store = get_typestore(Stores.ROS2_HUMBLE)
    with writer:
        connection = writer.add_connection("/imu/data_raw", "sensor_msgs/msg/Imu", typestore=store)
        for ns, raw in zip(time_ns.tolist(), messages, strict=True):
            writer.write(connection, ns, raw)
    assert list(folder.glob("*.db3.zstd")) and not list(folder.glob("*.db3"))
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    a, b = read_recording(plain), read_recording(folder)
    assert b.source == str(folder)
    assert np.array_equal(a.accel_mps2, b.accel_mps2)
    assert np.array_equal(a.time_s, b.time_s)
    assert list(scratch.iterdir()) == []  # the decompressed copy is gone
