"""The evaluation runner: agents x scenarios x seeds, each (agent, scenario) cell flown as one batched env.

A *cell* is one agent on one scenario: all its seeds fly together as the rows of one
:class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv` (row ``i`` seeded with ``seeds[i]``), the agent
batch-first over the rows.  Every cell of a run uses the same seed list, so for a given (scenario,
seed) every agent meets the same wind and sensor-noise realization: comparisons are paired.

Per step the runner records the truth (:class:`~fawtgym.eval.metrics.EpisodeRecorder`); a row that
fails (the env's termination rule, or the agent raising on a non-finite estimate) ends its episode
there, the env resets it on the next step and the agent resets that row only
(``agent.reset(info, rows=mask)``); the cell ends when every row has ended.

Results live in one folder per run (``--out``)::

    run.json                            agents, scenarios, seeds, baseline, the commands, package versions
    cells/<scenario>/<agent>.json       per-seed metrics of one cell (written last, atomically)
    cells/<scenario>/<agent>.npz        its decimated traces (written first, atomically)

A cell whose JSON exists with the same key (agent, scenario fields, seeds, record rate) is finished and
is skipped by a rerun, so an interrupted run loses only the cells in flight.  Same seeds, same numbers,
bitwise (the only field that differs between runs is ``timing``).  Cells run on local processes
(``backend="local"``, ``workers`` of them) or on a Ray cluster (``backend="ray"``, the optional extra
``ray``; ``ray.init(address=...)`` or a local instance); results are written by the calling process.
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import json
import multiprocessing
import os
import re
import tempfile
import time
import zipfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from fawtgym.core.checks import check_int, check_number, shown
from fawtgym.core.files import load_data

from .scenarios import Scenario, scenario_from_mapping, table4_duty

FORMAT = 1
DEFAULT_RECORD_HZ = 20.0
#: the most seeds of a cell: its vehicles fly as one batched env (HoverBatchEnv's MAX_NUM_ENVS)
MAX_SEEDS = 10**6
#: seeds are ints in [0, SEED_LIMIT) (the CLI's and numpy's 32-bit seeds)
SEED_LIMIT = 2**32
#: the highest trace rate [Hz] (a rate above the control rate keeps every step)
MAX_RECORD_HZ = 1e5
#: the lowest trace rate [Hz]: one sample per 1000 s (a rate of 1e-300 Hz made the sample interval overflow)
MIN_RECORD_HZ = 1e-3


def check_seeds(seeds: Any) -> list[int]:
    """A cell's seeds as a list of ints: 1 to :data:`MAX_SEEDS` distinct ints in [0, :data:`SEED_LIMIT`) (bool,
    float and str refused: a seed of 1.5 is no seed 1); ValueError naming them otherwise."""
    what = f"1 to {MAX_SEEDS} distinct int seeds in [0, 2**32)"
    if isinstance(seeds, (str, bytes)) or not isinstance(seeds, Iterable):
        raise ValueError(f"seeds must be {what}, got {shown(seeds)}")
    out = list(seeds)
    for s in out:
        if isinstance(s, (bool, np.bool_)) or not isinstance(s, (int, np.integer)) or not 0 <= s < SEED_LIMIT:
            raise ValueError(f"seeds must be {what}, got {shown(s)} in {shown(seeds)}")
    if not 1 <= len(out) <= MAX_SEEDS or len(set(out)) != len(out):
        raise ValueError(f"seeds must be {what}, got {len(out)} seeds ({len(set(out))} distinct)")
    return [int(s) for s in out]


def check_record_hz(record_hz: Any) -> float:
    """The trace rate [Hz] as a float in [:data:`MIN_RECORD_HZ`, :data:`MAX_RECORD_HZ`] (ValueError naming it
    otherwise)."""
    return check_number(record_hz, "record_hz", minimum=MIN_RECORD_HZ, inclusive_minimum=True,
                        maximum=MAX_RECORD_HZ, note="Hz (the traces' rate; above the control rate: every step)")


class CellError(RuntimeError):
    """A cell that could not be flown (its agent could not be built, or raised an unexpected error)."""


def slug(text: str) -> str:
    """A file-name-safe form of an agent or scenario name (a short hash keeps distinct names distinct)."""
    safe = re.sub(r"[^A-Za-z0-9+_.-]+", "_", text).strip("_")[:80]
    if safe == text:
        return safe
    return f"{safe}-{hashlib.sha1(text.encode()).hexdigest()[:8]}"


def cell_key(agent: str, scenario: Mapping[str, Any], seeds: Sequence[int], record_hz: float) -> str:
    """What identifies a cell's result: a rerun with the same key skips it."""
    blob = json.dumps({"format": FORMAT, "agent": agent, "scenario": scenario, "seeds": check_seeds(seeds),
                       "record_hz": check_record_hz(record_hz)}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def cell_paths(out: Path, agent: str, scenario: str) -> tuple[Path, Path]:
    """(JSON, NPZ) paths of a cell."""
    base = Path(out) / "cells" / slug(scenario) / slug(agent)
    return base.with_suffix(".json"), base.with_suffix(".npz")


def _wrench(info: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    t = info["truth"]
    return np.asarray(t["force"], dtype=float).copy(), np.asarray(t["torque"], dtype=float).copy()


def fly_cell(agent_name: str, scenario: Mapping[str, Any], seeds: Sequence[int],
             record_hz: float = DEFAULT_RECORD_HZ, progress: Callable[[int], Any] | None = None
             ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Fly one cell; returns (result record, traces).  Picklable arguments: runs in any worker process.

    ``progress``, if given, is called with 1 after every control step (e.g. a progress bar's ``update``).

    Raises :class:`CellError` if the agent cannot be built or raises an unexpected exception (a bug); a
    non-finite estimate or action (FloatingPointError) ends the alive rows' episodes as ``agent_error``.
    """
    import fawtgym  # noqa: F401  (registers the env and the observers)
    from fawtgym.agents.spec import agent_action_type, make_agent, observer_kwargs_of, parse_agent
    from fawtgym.envs.hover_batch_env import HoverBatchEnv

    from .metrics import EpisodeRecorder

    if not isinstance(scenario, Mapping) or not isinstance(scenario.get("name"), str):
        raise ValueError(f"scenario must be a mapping of a scenario's fields with its name (Scenario.to_dict()), "
                         f"got {shown(scenario)}")
    sc = scenario_from_mapping(scenario["name"], scenario)
    seeds, record_hz = check_seeds(seeds), check_record_hz(record_hz)
    t0 = time.perf_counter()
    try:  # an agent that cannot be built, whatever the reason, is a CellError
        spec = parse_agent(agent_name)
        action_type = agent_action_type(spec)
    except ValueError as exc:
        raise CellError(str(exc)) from exc
    try:
        env = HoverBatchEnv(num_envs=len(seeds), **sc.env_options(), action_type=action_type)
    except ValueError as exc:  # named as the scenario's
        raise ValueError(f"scenario {shown(sc.name)}: {exc}") from None
    try:
        try:
            agent = make_agent(spec, env)
        except ValueError as exc:
            raise CellError(str(exc)) from exc
        obs, info = env.reset(seed=seeds)
        agent.reset(info)
        space = env.single_action_space
        if not isinstance(space, spaces.Box):
            raise CellError(f"the env's action space must be a Box, got {type(space).__name__}")
        rec = EpisodeRecorder(len(seeds), env.dt, env.max_steps, env.setpoint, space.low, space.high,
                              env.hover_action()[0], record_hz)
        w_prev, w_cur = None, _wrench(info)
        ended_last = np.zeros(len(seeds), dtype=bool)
        for _ in range(env.max_steps):
            try:
                action = agent.act(obs, info)
            except FloatingPointError as exc:
                rec.end(rec.alive.copy(), "agent_error", str(exc).splitlines()[0])
                break
            estimate = agent.disturbance_estimate()
            att_sp = getattr(agent, "attitude_setpoint", None)
            obs, _, terminated, truncated, info = env.step(action)
            rec.step(info["truth"], action, att_sp, estimate, w_prev, info["action_clipped"])
            if progress is not None:
                progress(1)
            if terminated.any():
                rec.end(terminated, info["failure"])
            if not rec.alive.any():
                break
            if ended_last.any():  # the env reset these rows in this step: so does the agent
                agent.reset(info, rows=ended_last)
            ended_last = terminated | truncated
            w_prev, w_cur = w_cur, _wrench(info)
        on, off = sc.fan_schedule
        schedule = (sc.seconds, on, off) if table4_duty(sc) is not None and on is not None and off is not None else None
        episodes, traces = rec.finish(schedule)
    except CellError:
        raise
    except Exception as exc:  # a bug in an agent or plugin: report it with the cell's name
        raise CellError(f"{type(exc).__name__}: {exc}".splitlines()[0]) from exc
    finally:
        env.close()
    observer = getattr(agent, "observer", None)
    result = {
        "format": FORMAT, "key": cell_key(agent_name, scenario, seeds, record_hz), "agent": agent_name,
        "scenario": dict(scenario), "seeds": seeds, "record_hz": record_hz, "steps": int(rec.steps),
        "dt": env.dt, "episodes": episodes,
        "observer": None if observer is None else {"name": observer.name, "channels": sorted(observer.channels),
                                                   "kwargs": observer_kwargs_of(spec)},
        "timing": {"wall_seconds": time.perf_counter() - t0,
                   "vehicle_seconds": float(sum(e["time_flown"] for e in episodes))},
    }
    return result, traces


def _atomic_write(path: Path, write: Callable[[Any], None], binary: bool) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb" if binary else "w") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_cell(out: Path, result: Mapping[str, Any], traces: Mapping[str, np.ndarray]) -> Path:
    """Write a cell (traces first, then the JSON that marks it finished), each atomically."""
    js, npz = cell_paths(out, result["agent"], result["scenario"]["name"])
    arrays = dict(traces)
    _atomic_write(npz, lambda fh: np.savez_compressed(fh, allow_pickle=False, **arrays), binary=True)
    _atomic_write(js, lambda fh: json.dump(result, fh, indent=1, allow_nan=False), binary=False)
    return js


def read_cell(path: Path) -> dict[str, Any] | None:
    """A finished cell's record (None if absent or unreadable)."""
    try:
        record = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):  # missing, not UTF-8, not JSON, an int beyond Python's int-to-str limit
        return None
    return record if isinstance(record, dict) else None


def read_traces(out: Path, agent: str, scenario: str) -> dict[str, np.ndarray] | None:
    """A cell's traces (None if absent)."""
    _, npz = cell_paths(out, agent, scenario)
    if not npz.is_file():
        return None
    try:
        with np.load(npz, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:  # empty, truncated or not an npz at all
        why = ("empty" if isinstance(exc, EOFError) else "cut short or not a zip archive"
               if isinstance(exc, zipfile.BadZipFile) else "not an archive of arrays")
        raise ValueError(f"{npz} is not a readable trace file of 'fawtgym eval' ({why}); delete it and "
                         f"{npz.with_suffix('.json').name} beside it, and run the cell again") from None


def is_finished(out: Path, agent: str, scenario: Mapping[str, Any], seeds: Sequence[int], record_hz: float) -> bool:
    js, npz = cell_paths(out, agent, scenario["name"])
    rec = read_cell(js)
    return rec is not None and npz.is_file() and rec.get("key") == cell_key(agent, scenario, seeds, record_hz)


def versions() -> dict[str, str]:
    """Versions of the packages that decide the numbers."""
    import importlib.metadata as md
    import platform

    out = {"python": platform.python_version()}
    for pkg in ("fawtgym", "numpy", "scipy", "mujoco", "gymnasium"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    return out


def update_run_file(out: Path, agents: Sequence[str], scenarios: Sequence[Scenario], seeds: Sequence[int],
                    baseline: str | None, command: str, record_hz: float) -> dict[str, Any]:
    """Create or extend ``run.json`` (agents and scenarios accumulate; the seeds of a run folder are fixed)."""
    path = Path(out) / "run.json"
    old = read_run(path) if path.is_file() else None
    run: dict[str, Any] = old or {"format": FORMAT, "agents": [], "scenarios": [], "seeds": list(seeds),
                                  "record_hz": record_hz, "commands": []}
    if list(run["seeds"]) != list(seeds) or float(run.get("record_hz", record_hz)) != float(record_hz):
        raise ValueError(f"{out} holds a run with seeds {shown(run['seeds'])} at {run.get('record_hz')} Hz traces; "
                         f"use the same --seeds/--record-hz to extend it or another --out (got seeds "
                         f"{shown(list(seeds))})")
    run["agents"] = list(dict.fromkeys([*run["agents"], *agents]))
    known = {s["name"]: s for s in run["scenarios"]}
    for sc in scenarios:
        if sc.name in known and known[sc.name] != sc.to_dict():
            raise ValueError(f"{out} already has a different scenario named {shown(sc.name)}; rename yours or use "
                             "another --out")
        known[sc.name] = sc.to_dict()
    run["scenarios"] = list(known.values())
    if baseline is not None:
        run["baseline"] = baseline
    run["commands"] = [*run.get("commands", []), command][-20:]
    run["versions"] = versions()
    Path(out).mkdir(parents=True, exist_ok=True)
    _atomic_write(path, lambda fh: json.dump(run, fh, indent=1), binary=False)
    return run


def _job(args: tuple[str, dict[str, Any], list[int], float]) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    return fly_cell(*args)


def run_cells(out: Path, agents: Sequence[str], scenarios: Sequence[Scenario], seeds: Sequence[int], *,
              backend: str = "local", workers: int = 2, ray_address: str | None = None,
              record_hz: float = DEFAULT_RECORD_HZ, progress: bool = True,
              on_cell: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Fly every unfinished (agent, scenario) cell and write it; returns a summary.

    Summary: ``{"done": [(agent, scenario)], "skipped": [...], "errors": {(agent, scenario): message},
    "wall_seconds": float}``.
    """
    if backend not in ("local", "ray"):
        raise ValueError(f"backend must be 'local' or 'ray', got {shown(backend)}")
    workers = check_int(workers, "workers", 1, 4096)
    if isinstance(agents, str) or not all(isinstance(a, str) for a in agents):
        raise ValueError(f"agents must be a list of agent names, got {shown(agents)}")
    if isinstance(scenarios, str) or not all(isinstance(sc, Scenario) for sc in scenarios):
        raise ValueError(f"scenarios must be a list of Scenario objects (fawtgym.eval.scenarios.resolve_scenarios "
                         f"makes them from names and files), got {shown(scenarios)}")
    from fawtgym.agents.spec import parse_agent

    for agent in agents:  # a bad name is refused before any cell flies, at every worker count
        parse_agent(agent)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out {shown(str(out))} is a file, not a results folder")
    seeds, record_hz = check_seeds(seeds), check_record_hz(record_hz)
    jobs, skipped = [], []
    for sc in scenarios:
        scd = sc.to_dict()
        for agent in agents:
            if is_finished(out, agent, scd, seeds, record_hz):
                skipped.append((agent, sc.name))
            else:
                jobs.append((agent, scd, seeds, record_hz))
    summary: dict[str, Any] = {"done": [], "skipped": skipped, "errors": {}}
    t0 = time.perf_counter()

    def finished(job: tuple, result: tuple | BaseException) -> None:
        agent, scd = job[0], job[1]
        if isinstance(result, BaseException):
            summary["errors"][(agent, scd["name"])] = str(result).splitlines()[0] if str(result) else repr(result)
            return
        record, traces = result
        write_cell(out, record, traces)
        summary["done"].append((agent, scd["name"]))
        if on_cell is not None:
            on_cell(record)

    bar = _progress(len(jobs), progress, len(skipped))
    try:
        if not jobs:
            pass
        elif backend == "ray":
            _run_ray(jobs, ray_address, finished, bar)
        elif workers == 1 or len(jobs) == 1:
            for job in jobs:
                try:
                    res: Any = _job(job)
                except Exception as exc:  # as a worker process's future reports it: the same summary at every count
                    res = exc
                finished(job, res)
                bar.update(1)
        else:
            ctx = multiprocessing.get_context("spawn")
            with cf.ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx) as pool:
                futures = {pool.submit(_job, job): job for job in jobs}
                for fut in cf.as_completed(futures):
                    error = fut.exception()
                    finished(futures[fut], error if error is not None else fut.result())
                    bar.update(1)
    finally:
        bar.close()
    summary["wall_seconds"] = time.perf_counter() - t0
    return summary


def _run_ray(jobs: list[tuple], address: str | None, finished: Callable, bar: Any) -> None:
    try:
        import ray
    except ImportError as exc:
        raise ValueError("--backend ray needs Ray: pip install 'fawtgym[ray]'") from exc
    started = False
    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(_job)
        pending = {remote.remote(job): job for job in jobs}
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                job = pending.pop(ref)
                try:
                    res: Any = ray.get(ref)
                except Exception as exc:  # the task raised: report its message
                    cause = getattr(exc, "cause", None) or exc
                    res = CellError(str(cause).splitlines()[0] if str(cause) else repr(cause))
                finished(job, res)
                bar.update(1)
    finally:
        if started:
            ray.shutdown()


class _NoBar:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


def _progress(total: int, enabled: bool, skipped: int) -> Any:
    if not enabled or total == 0:
        return _NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=f"cells ({skipped} finished before)" if skipped else "cells", unit="cell",
                dynamic_ncols=True)


def read_run(path: Path) -> dict[str, Any]:
    """A results folder's ``run.json``, its shape checked (ValueError naming the file and the first bad field)."""
    run = load_data(path, "run file")
    bad = None
    if not isinstance(run, dict):
        bad = f"must hold a JSON object, got {type(run).__name__}"
    elif not (isinstance(run.get("agents"), list) and all(isinstance(a, str) and a for a in run["agents"])):
        bad = f"agents must be a list of agent names, got {shown(run.get('agents'))}"
    elif not (isinstance(run.get("scenarios"), list)
              and all(isinstance(sc, dict) and isinstance(sc.get("name"), str) for sc in run["scenarios"])):
        bad = f"scenarios must be a list of scenario records with names, got {shown(run.get('scenarios'))}"
    elif not isinstance(run.get("seeds"), list):
        bad = f"seeds must be a list, got {shown(run.get('seeds'))}"
    if bad is not None:
        raise ValueError(f"{path} is not a run file of 'fawtgym eval': {bad}")
    try:
        check_seeds(run["seeds"])
        if "record_hz" in run:
            check_record_hz(run["record_hz"])
    except ValueError as exc:
        raise ValueError(f"{path} is not a run file of 'fawtgym eval': {exc}") from None
    return run


def load_run(out: Path) -> tuple[dict[str, Any], dict[tuple[str, str], dict[str, Any]]]:
    """``(run.json, {(agent, scenario): cell record})`` of a results folder; ValueError if it is not one."""
    out = Path(out)
    run_path = out / "run.json"
    if not run_path.is_file():
        raise ValueError(f"{str(out)!r} is not a results folder of 'fawtgym eval' (no run.json)")
    run = read_run(run_path)
    cells = {}
    for sc in run["scenarios"]:
        for agent in run["agents"]:
            js, _ = cell_paths(out, agent, sc["name"])
            rec = read_cell(js)
            if rec is not None and rec.get("key") == cell_key(agent, sc, run["seeds"], run.get("record_hz",
                                                                                            DEFAULT_RECORD_HZ)):
                cells[(agent, sc["name"])] = rec
    return run, cells


def iter_missing(run: Mapping[str, Any], cells: Mapping[tuple[str, str], Any]) -> Iterable[tuple[str, str]]:
    """(agent, scenario) pairs of a run that have no finished cell."""
    for sc in run["scenarios"]:
        for agent in run["agents"]:
            if (agent, sc["name"]) not in cells:
                yield agent, sc["name"]
