"""Simulation of the devices and the human hand in MuJoCo (imported lazily: ``import
virtmech`` does not import MuJoCo).

Stable API (docs/simulation.md):

- ``run(scenario, seed=None, progress=False) -> SimResult``: runs a scenario (a
  ``virtmech.scenarios.Scenario``, a shipped name or a TOML path) headless (the servo-rate
  loop is C++, ``virtmech._sim``, imported here lazily); ``sink=`` receives
  the log block by block as it is produced (``virtmech.sim.output.CsvLog`` writes log.csv
  so), ``keep_log=False`` keeps none of it in memory.
- ``SimResult``: ``.log`` (one row per control cycle), ``.columns``, ``.col(name)``,
  ``.sim_time_s``, ``.wall_time_s``, ``.info``; ``virtmech.sim.output.write_run`` writes
  ``log.csv`` and ``run.json``.
- ``build_mjcf(device, ...)``: the MJCF model of a device.
"""

from __future__ import annotations

from typing import Any

__all__ = ["SimResult", "build_mjcf", "run"]


def run(
    scenario: Any,
    seed: int | None = None,
    progress: bool = False,
    **streaming: Any,
):
    """virtmech.sim.run_loop.run: `streaming` takes sink, keep_log, chunk_s and spill_dir."""
    from .run_loop import run as _run

    return _run(scenario, seed=seed, progress=progress, **streaming)


def __getattr__(name: str) -> Any:
    if name == "SimResult":
        from .log import SimResult

        return SimResult
    if name == "build_mjcf":
        from .model import build_mjcf

        return build_mjcf
    raise AttributeError(name)
