"""Generate a pipeline's simulated recordings (the self-contained demo and tests)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from wheelcal.batch.pipeline import Pipeline

#: First sample of the first simulated recording: 2024-03-12 09:00:00 UTC.
FIRST_START_UNIX_NS = 1_710_234_000_000_000_000
#: Simulated recordings start this far apart (10 min: a spin, notes, the next spin).
SPACING_NS = 600_000_000_000


def simulate_inputs(
    pipeline: Pipeline, progress: Callable[[str], None] | None = None
) -> list[Path]:
    """Write the [simulate] recordings that do not exist yet; returns the new files.

    Recording i uses the random stream ``default_rng([seed, i])``: the same
    pipeline always produces the same files, and each has its own hand spin.
    Recording i starts at :data:`FIRST_START_UNIX_NS` + i · :data:`SPACING_NS`
    (sessions recorded one after another, each with its own start time).
    """
    spec = pipeline.simulate
    if spec is None:  # before the imports: the simulator costs ~1 s to import (scipy.signal)
        return []
    from wheelcal.io import write_recording
    from wheelcal.simulate import NoiseSpec, Quantiser, preset, simulate, simulate_session

    made = []
    for i, path in enumerate(pipeline.simulated_paths()):
        if path.exists():
            continue
        rng = np.random.default_rng([spec.seed, i])
        scenario = preset(spec.preset, rng=rng)
        if spec.noise_mps2 is not None or spec.bandwidth_hz is not None:
            std = spec.noise_mps2 if spec.noise_mps2 is not None else scenario.noise.std_mps2
            scenario = dataclasses.replace(
                scenario, noise=NoiseSpec(std, bandwidth_hz=spec.bandwidth_hz)
            )
        if spec.quantise:
            scenario = dataclasses.replace(scenario, quantiser=Quantiser())
        info = scenario.info.merged(sensor_id=spec.sensor_id, mounting_id=spec.mounting_id)
        scenario = dataclasses.replace(scenario, info=info)
        path.parent.mkdir(parents=True, exist_ok=True)
        start_ns = FIRST_START_UNIX_NS + i * SPACING_NS
        if spec.push_and_stop:
            recording = simulate_session(
                scenario, rng, epoch_unix_ns=start_ns, source=str(path)
            ).recording
        else:
            recording = simulate(scenario, rng, epoch_unix_ns=start_ns, source=str(path)).recording
        write_recording(recording, path, encoding=spec.format, batch_size=20)
        made.append(path)
        if progress is not None:
            progress(f"simulated {path} ({i + 1}/{spec.count})")
    return made
