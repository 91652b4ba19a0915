"""Simulated recordings and pipeline files for the batch tests (shared, not tests)."""

from __future__ import annotations

from pathlib import Path

from wheelcal.cli.main import main


def simulated_recordings(folder: Path, stems, seed: int, free_spin_only: bool = True) -> Path:
    """``<stem>.mcap`` per stem from ``wheelcal simulate`` (seeds seed, seed + 1, …)."""
    for i, stem in enumerate(stems):
        args = ["simulate", str(folder / f"{stem}.mcap"), "--seed", str(seed + i)]
        assert main(args + (["--free-spin-only"] if free_spin_only else [])) == 0
    return folder


def pipeline_file(path: Path, output: Path, globs: str, workers: int = 1, extra: str = "") -> Path:
    """A pipeline TOML: ``globs`` into ``output``, radius 0.28 m by default."""
    path.write_text(
        f'[pipeline]\nname = "t"\noutput = "{output}"\n'
        f'[inputs]\nglobs = ["{globs}"]\n[defaults]\nradius_m = 0.28\n'
        f"[executor]\nworkers = {workers}\n{extra}"
    )
    return path
