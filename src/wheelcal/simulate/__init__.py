"""Simulated recordings with known truth (speaks the model's parameter types)."""

from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.noise import NoiseSpec, Quantiser
from wheelcal.simulate.presets import PRESETS, hand_spin, preset, random_setup, table1, table2
from wheelcal.simulate.session import SessionPlan, SimulatedFullSession, simulate_session
from wheelcal.simulate.simulator import Scenario, SimulatedSession, simulate
from wheelcal.simulate.temperature import TemperatureSpec

__all__ = [
    "PRESETS",
    "GyroSpec",
    "NoiseSpec",
    "Quantiser",
    "Scenario",
    "SessionPlan",
    "SimulatedFullSession",
    "SimulatedSession",
    "TemperatureSpec",
    "hand_spin",
    "preset",
    "random_setup",
    "simulate",
    "simulate_session",
    "table1",
    "table2",
]
