"""Simulated recordings with known truth (speaks the model's parameter types).

Layer 3 (above ``recording``, beside ``io`` and ``estimate``, below ``closedloop``).
"""

from wheelcal.simulate.field import (
    FieldScenario,
    FieldSimulation,
    FieldTruth,
    Glitches,
    VibrationSpec,
    WheelGeometry,
    bench_spin,
    car_drive,
    robot_drive,
    simulate_field,
    stand_spin,
    wheelchair_coast,
)
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.mountings import mounting_near
from wheelcal.simulate.noise import NoiseSpec, Quantiser
from wheelcal.simulate.presets import (
    PRESETS,
    hand_spin,
    preset,
    random_rotation,
    random_setup,
    table1,
    table2,
)
from wheelcal.simulate.session import SessionPlan, SimulatedFullSession, simulate_session
from wheelcal.simulate.simulator import Scenario, SimulatedSession, simulate
from wheelcal.simulate.temperature import TemperatureSpec

__all__ = [
    "PRESETS",
    "FieldScenario",
    "FieldSimulation",
    "FieldTruth",
    "Glitches",
    "GyroSpec",
    "NoiseSpec",
    "Quantiser",
    "Scenario",
    "SessionPlan",
    "SimulatedFullSession",
    "SimulatedSession",
    "TemperatureSpec",
    "VibrationSpec",
    "WheelGeometry",
    "bench_spin",
    "car_drive",
    "hand_spin",
    "mounting_near",
    "preset",
    "random_rotation",
    "random_setup",
    "robot_drive",
    "simulate",
    "simulate_field",
    "simulate_session",
    "stand_spin",
    "table1",
    "table2",
    "wheelchair_coast",
]
