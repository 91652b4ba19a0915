"""One IMU mounted several ways on the wheel: what the gyroscope's full matrix needs.

A session's gyro reading sees the gyro's response M along one direction only,
the wheel axis d = −R e_Z in the sensor frame.  Remounting the sensor so that
the wheel axis lies near its x, then its y, then its z axis gives three
independent directions, and M is determined (``wheelcal.closedloop.gyro_matrix``).

:func:`mounting_near` turns Table II's mounting (the wheel axis 33° from the
sensor's z) by a relabelling of the sensor's axes — the sensor turned by 120°
about its (1, 1, 1) diagonal — so the wheel axis lies as near the sensor's x or
y as it lies near z: every axis of the accelerometer still sees gravity turn,
so every mounting calibrates it fully.  :func:`imu_sessions` simulates whole
sessions (rest, push, free spin, brake, rest) of one device in each.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from wheelcal.model import Rotation
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.hostile import table2_truth
from wheelcal.simulate.noise import NoiseSpec
from wheelcal.simulate.presets import TABLE2_EULER_DEG, hand_spin
from wheelcal.simulate.session import SimulatedFullSession, simulate_session
from wheelcal.simulate.simulator import Scenario

#: The sensor's axes relabelled x → y → z → x: turns the wheel axis from near z to near x.
_CYCLE = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_TURNS = {"z": 0, "x": 1, "y": 2}


def mounting_near(axis: str, base: Rotation | None = None) -> Rotation:
    """R (bench → sensor) with the wheel axis near the sensor's ``axis`` ("x", "y" or "z").

    ``base`` (default Table II's mounting) is the mounting near z; the others
    relabel its sensor axes cyclically (a proper rotation of the sensor).
    """
    if axis not in _TURNS:
        raise ValueError(f"axis must be 'x', 'y' or 'z', got {axis!r}")
    base = base or Rotation.from_euler_deg(*TABLE2_EULER_DEG)
    return Rotation(np.linalg.matrix_power(_CYCLE, _TURNS[axis]) @ base.matrix)


def imu_sessions(
    rng: np.random.Generator,
    gyro: GyroSpec,
    axes: Sequence[str] = ("x", "y", "z"),
    spins: int = 3,
    duration_s: float = 90.0,
    rate_hz: float = 200.0,
    sensor_id: str = "imu",
) -> list[SimulatedFullSession]:
    """``spins`` whole sessions of one IMU (accelerometer of Table II, ``gyro``) per mounting.

    Mounting ids are ``wheel-axis-near-<axis>``; each session its own hand spin.
    """
    out = []
    for axis in axes:
        rotation = mounting_near(axis)
        for _ in range(spins):
            truth = table2_truth(hand_spin(rng, duration_s, direction=1), rotation)
            scenario = Scenario(
                truth=truth,
                duration_s=duration_s,
                rate_hz=rate_hz,
                noise=NoiseSpec(0.08),
                gyro=gyro,
            )
            info = scenario.info.merged(sensor_id=sensor_id, mounting_id=f"wheel-axis-near-{axis}")
            scenario = dataclasses.replace(scenario, info=info)
            out.append(simulate_session(scenario, rng, source=f"<{sensor_id} near {axis}>"))
    return out
