"""``wheelcal plan`` — predicted precision of a planned bench, before building it."""

from __future__ import annotations

import argparse
import json

from wheelcal.cli.convert_cmd import radius_metres
from wheelcal.cli.errors import UsageError
from wheelcal.cli.options import positive_float

#: The command's one-line help and its --help description.
HELP = "predicted precision of a planned setup (and the best sensor mounting)"
DESCRIPTION = (
    "Predict the σ every parameter will have (Cramér–Rao bound: the joint fit attains "
    "it, and reports it on real data), the systematic budget of the geometry mode, "
    "the warnings calibrate would print, and — with --mounting any — the mounting and "
    "tilt that minimise the worst offset σ.  Defaults: the paper's bench (r = 0.28 m "
    "± 1 mm, tilt 45°, 90 s at 200 Hz, MPU-9250 noise 0.08 m/s²)."
)


def register(sub) -> None:
    """Add the ``plan`` parser."""
    p = sub.add_parser("plan", help=HELP, description=DESCRIPTION)
    _bench_arguments(p.add_argument_group("bench"))
    _recording_arguments(p.add_argument_group("recording"))
    _systematic_arguments(p.add_argument_group("systematic inputs"))
    _search_arguments(p.add_argument_group("search and output"))
    p.set_defaults(handler=run)


def _bench_arguments(b) -> None:
    """Geometry mode, radius, tilt and mounting of the planned bench."""
    b.add_argument(
        "--geometry",
        choices=("radius", "tilt", "vertical"),
        default="radius",
        help="what you will measure: the radius (default), the tilt, or a vertical wheel",
    )
    b.add_argument(
        "--radius",
        type=radius_metres,
        default=0.28,
        metavar="M",
        help="the sensor's distance from the axle in metres (default 0.28)",
    )
    b.add_argument(
        "--radius-std",
        type=float,
        default=1e-3,
        metavar="M",
        help="its uncertainty in metres (radius mode; default 0.001)",
    )
    b.add_argument(
        "--tilt-deg",
        type=float,
        help="tilt of the wheel axis from vertical (default 45; 90 vertical)",
    )
    b.add_argument(
        "--tilt-std-deg", type=float, default=0.5, help="levelling uncertainty (tilt/vertical)"
    )
    b.add_argument(
        "--mounting",
        nargs="+",
        metavar="DEG",
        help="sensor mounting: three Euler angles (ZYX, bench → sensor; default: the paper's "
        "30 20 25), or 'any' to search the best one",
    )


def _recording_arguments(r) -> None:
    """Length, rate, noise and spin of the planned recording."""
    r.add_argument(
        "--duration", type=positive_float, default=90.0, metavar="S", help="free-spin window"
    )
    r.add_argument("--rate", type=positive_float, default=200.0, metavar="HZ", help="sampling rate")
    r.add_argument(
        "--noise", type=positive_float, default=0.08, metavar="MPS2", help="noise σ per sample"
    )
    r.add_argument("--bandwidth-hz", type=positive_float, help="low-pass corner of the noise")
    r.add_argument(
        "--omega-start", type=positive_float, default=9.0, metavar="RADPS", help="spin at the start"
    )
    r.add_argument(
        "--omega-end",
        type=positive_float,
        default=5.5,
        metavar="RADPS",
        help="spin at the end (quadratic drag in between)",
    )
    r.add_argument(
        "--full-scale-g", type=positive_float, metavar="G", help="sensor range: warn if clipping"
    )
    r.add_argument(
        "--gyro-noise-density",
        type=positive_float,
        default=0.01,
        metavar="DPS_RTHZ",
        help="the IMU gyro's white noise, °/s/√Hz, for its planned full matrix (MPU-9250: 0.01)",
    )
    r.add_argument(
        "--gyro-sessions",
        type=int,
        default=3,
        metavar="N",
        help="spins per mounting planned for the gyro's full matrix (3 mountings)",
    )


def _systematic_arguments(s) -> None:
    """The uncertainties behind the systematic budget: gravity and the sample clock."""
    s.add_argument(
        "--gravity", type=positive_float, metavar="MPS2", help="local gravity you will give"
    )
    s.add_argument(
        "--gravity-std",
        type=float,
        metavar="MPS2",
        help="its uncertainty (default 0.02 without --gravity, 1e-4 with it)",
    )
    s.add_argument("--clock-ppm", type=float, default=100.0, help="sample-clock uncertainty (ppm)")


def _search_arguments(o) -> None:
    """The mounting search (``--mounting any``) and what is printed."""
    o.add_argument(
        "--objective",
        choices=("statistical", "total"),
        default="statistical",
        help="what --mounting any minimises: the worst offset σ, or σ ⊕ systematic",
    )
    o.add_argument(
        "--tilt-range",
        nargs=2,
        type=float,
        default=(10.0, 80.0),
        metavar=("LO", "HI"),
        help="tilts --mounting any may choose (deg)",
    )
    o.add_argument("--fixed-tilt", action="store_true", help="--mounting any keeps your tilt")
    o.add_argument("--no-tradeoffs", action="store_true", help="skip the geometry-mode table")
    o.add_argument("--json", action="store_true", help="print JSON instead of the table")


def run(args: argparse.Namespace) -> int:
    """Plan and print."""
    from wheelcal.estimate.joint import DEFAULT_GRAVITY_STD_MPS2, GIVEN_GRAVITY_STD_MPS2
    from wheelcal.model import STANDARD_GRAVITY_MPS2
    from wheelcal.plan import (
        DEFAULT_TILTS_DEG,
        PAPER_MOUNTING_EULER_DEG,
        MountingSearch,
        PlannedSetup,
        plan_report,
        render,
    )
    from wheelcal.simulate import GyroSpec

    mounting, search_mounting = _mounting(args.mounting, PAPER_MOUNTING_EULER_DEG)
    tilt = args.tilt_deg
    if args.geometry == "vertical":
        if tilt is not None and tilt != 90.0:
            raise UsageError("--geometry vertical means tilt 90°: drop --tilt-deg")
        tilt = 90.0
    elif tilt is None:
        tilt = 45.0
    gravity_std = args.gravity_std
    if gravity_std is None:
        gravity_std = DEFAULT_GRAVITY_STD_MPS2 if args.gravity is None else GIVEN_GRAVITY_STD_MPS2
    try:
        setup = PlannedSetup(
            radius_m=args.radius,
            radius_std_m=args.radius_std,
            tilt_deg=tilt,
            tilt_std_deg=args.tilt_std_deg,
            mounting_euler_deg=mounting,
            duration_s=args.duration,
            rate_hz=args.rate,
            noise_std_mps2=args.noise,
            noise_bandwidth_hz=args.bandwidth_hz,
            omega_start_radps=args.omega_start,
            omega_end_radps=args.omega_end,
            geometry=args.geometry,
            gravity_mps2=args.gravity if args.gravity is not None else STANDARD_GRAVITY_MPS2,
            gravity_std_mps2=gravity_std,
            clock_std_ppm=args.clock_ppm,
            full_scale_g=args.full_scale_g,
        )
        search = (
            MountingSearch(
                free_tilt=not args.fixed_tilt,
                tilt_range_deg=tuple(args.tilt_range),
                objective=args.objective,
            )
            if search_mounting
            else None
        )
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    tilts = None if args.no_tradeoffs else DEFAULT_TILTS_DEG
    if args.gyro_sessions < 1:
        raise UsageError(f"--gyro-sessions must be >= 1, got {args.gyro_sessions}")
    gyro = GyroSpec(noise_density_dps_rthz=args.gyro_noise_density)
    report = plan_report(
        setup, search=search, tradeoff_tilts_deg=tilts, gyro=gyro, gyro_sessions=args.gyro_sessions
    )
    if args.json:
        print(json.dumps(report.to_dict(), indent=2, ensure_ascii=False))
    else:
        print(render(report), end="")
    return 0


def _mounting(values: list[str] | None, default: tuple[float, float, float]):
    """(Euler angles, search?) from ``--mounting``: three angles or ``any``."""
    if values is None:
        return default, False
    if len(values) == 1 and values[0].lower() == "any":
        return default, True
    if len(values) != 3:
        raise UsageError("--mounting takes three Euler angles (deg) or the word 'any'")
    try:
        return tuple(float(v) for v in values), False
    except ValueError:
        raise UsageError(f"--mounting: not three numbers: {' '.join(values)}") from None
