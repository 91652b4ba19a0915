"""Issue 28: the CSVs people have, in the exact layout their tools write.

* an Arduino sketch printing ``millis,ax,ay,az`` in raw int16 counts of an
  MPU-6050-class sensor at ±8 g (4096 counts/g), as ``Serial.print`` writes them;
* the same in mg with a ``micros`` time column;
* phyphox's "Acceleration (without g)"-style raw export: quoted headers
  ``"Time (s)","Acceleration x (m/s^2)",…,"Absolute acceleration (m/s^2)"``
  and numbers as Java's ``DecimalFormat("0.000000000E0")`` writes them, in the
  comma variant and in the semicolon / decimal-comma variant.
"""

import numpy as np
import pytest

from wheelcal.cli.main import main
from wheelcal.io import read_recording
from wheelcal.simulate import table2
from wheelcal.simulate.session import simulate_session

G = 9.80665


@pytest.fixture(scope="module")
def session():
    return simulate_session(table2(rng=np.random.default_rng(21)), np.random.default_rng(22))


def _java_sci(value: float, comma: bool = False) -> str:
    """``DecimalFormat("0.000000000E0")``: 9 decimals, the exponent unpadded (E-2, E0, E1)."""
    mantissa, exponent = f"{value:.9E}".split("E")
    text = f"{mantissa}E{int(exponent)}"
    return text.replace(".", ",") if comma else text


def _arduino(path, session, counts_per_g, time_name, time_scale):
    rec = session.recording
    t = np.round(rec.time_s * time_scale).astype(np.int64)
    raw = np.clip(np.round(rec.accel_mps2 / G * counts_per_g), -32768, 32767).astype(np.int64)
    lines = [f"{time_name},ax,ay,az"] + [
        f"{ti},{x},{y},{z}" for ti, (x, y, z) in zip(t.tolist(), raw.tolist(), strict=True)
    ]
    path.write_text("\r\n".join(lines) + "\r\n")  # Serial.println ends lines with CR LF
    return raw


def test_arduino_raw_counts_need_and_take_their_scale(tmp_path, session, capsys):
    csv = tmp_path / "log.csv"
    raw = _arduino(csv, session, 4096, "millis", 1e3)
    out = tmp_path / "log.mcap"
    assert main(["convert", str(csv), str(out), "--radius", "0.28"]) == 1
    assert "--accel-unit" in capsys.readouterr().err  # no unit in the header: say how
    assert main(["convert", str(csv), str(out), "--accel-unit", "m/s^2"]) == 1
    err = capsys.readouterr().err
    assert "raw counts at 4096 per g" in err
    assert "--accel-unit counts --counts-per-g 4096" in err
    args = ["--accel-unit", "counts", "--counts-per-g", "4096", "--radius", "0.28"]
    assert main(["convert", str(csv), str(out), *args]) == 0
    assert "time unit ms from the column name 'millis'" in capsys.readouterr().out
    back = read_recording(out)
    np.testing.assert_allclose(back.accel_mps2, raw / 4096 * G, rtol=1e-12)
    assert back.rate_hz == pytest.approx(200.0)


def test_milli_g_with_a_micros_column(tmp_path, session):
    rec = session.recording
    csv = tmp_path / "mg.csv"
    t = np.round(rec.time_s * 1e6).astype(np.int64)
    mg = np.round(rec.accel_mps2 / G * 1000, 1)
    rows = [f"{a},{b:.1f},{c:.1f},{d:.1f}" for a, (b, c, d) in zip(t, mg.tolist(), strict=True)]
    csv.write_text("micros,ax,ay,az\n" + "\n".join(rows) + "\n")
    out = tmp_path / "mg.mcap"
    assert main(["convert", str(csv), str(out), "--accel-unit", "mg"]) == 0
    back = read_recording(out, info_overrides={"radius_m": 0.28})
    np.testing.assert_allclose(back.accel_mps2, mg / 1000 * G, rtol=1e-12)


@pytest.mark.parametrize("variant", ["comma", "semicolon"])
def test_phyphox_export_reads_with_the_unit_its_header_states(tmp_path, session, variant):
    rec = session.recording
    comma = variant == "semicolon"
    sep = ";" if comma else ","
    names = ["Time (s)", "Acceleration x (m/s^2)", "Acceleration y (m/s^2)"]
    names += ["Acceleration z (m/s^2)", "Absolute acceleration (m/s^2)"]
    header = sep.join(f'"{n}"' for n in names)
    t = rec.time_s - rec.time_s[0]
    absolute = np.linalg.norm(rec.accel_mps2, axis=1)
    rows = [
        sep.join(_java_sci(v, comma) for v in (ti, *a, m))
        for ti, a, m in zip(t, rec.accel_mps2, absolute, strict=True)
    ]
    csv = tmp_path / "Raw Data.csv"
    csv.write_text(header + "\n" + "\n".join(rows) + "\n")
    out = tmp_path / "phone.mcap"
    assert main(["convert", str(csv), str(out), "--radius", "0.28"]) == 0  # no --accel-unit
    back = read_recording(out)
    expected = np.array([[float(_java_sci(v)) for v in a] for a in rec.accel_mps2])
    np.testing.assert_allclose(back.accel_mps2, expected, rtol=1e-15)
    stamps = np.array([float(_java_sci(v)) for v in t])
    np.testing.assert_allclose(back.time_s, stamps - stamps[0], atol=1e-9)
    # a unit given that contradicts the header is refused, not silently preferred
    assert main(["convert", str(csv), str(out), "--accel-unit", "g", "--force"]) == 1
