"""Issue 14: a row's wind must not depend on other rows.

Row i of an N-row :class:`~fawtgym.envs.wind_cohorts.BatchWind` (shared mode for the time-invariant models,
cohorts for a fan schedule), given the same sample points and velocities, is the one-row BatchWind (the single
env's wind) with that row's wind seed: at the first reset, and when some rows restart while the others fly, in
the env's next-step protocol (the restarted rows step with the others) and its same-step one (``first_step``
of the restarted rows alone).  The law is the same per-row loop on the same inputs: bitwise (tolerance policy,
tests/_tolerance.py, case 1).  The env test checks the same through HoverBatchEnv / HoverEnv: HoverEnv is
HoverBatchEnv(1) (one code path, the physics included), so row i of the 3-row env is bitwise the single env with
that row's seed (its wind and the vehicle state it is sampled at: the whole ``info["truth"]``), and the test
catches a row coupling at the rounding level too (case 1; a one-ulp change of one row's action fails it).
"""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.core.frames import FAWT_HOVER_POINT_NED
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.hover_env import HoverEnv
from fawtgym.envs.wind import make_wind
from fawtgym.envs.wind_cohorts import BatchWind

WINDS = {
    "fawt-50": "fawt-50",
    "fawt-50 rates": {"name": "fawt-50", "rates": True},
    "fawt schedule": {"name": "fawt", "duty": 0.4, "on_time": 0.02, "off_time": 0.1, "spin_tau": 0.03},
    "dryden-light": "dryden-light",
    "dryden-severe rates mean": {"name": "dryden-severe", "rates": True, "mean_wind": 4.0, "direction_deg": 30.0},
    "gust-1cos": {"name": "gust-1cos", "start_time": 0.02, "length": 0.5},
}
DT = 0.01


def _seed(row: int, episode: int) -> tuple[int, np.random.SeedSequence]:
    """A row's wind seed of one episode, as the env makes it: an int and a SeedSequence child of it."""
    entropy = 1000 * row + episode
    return entropy, np.random.SeedSequence(entropy).spawn(2)[0]


def _inputs(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample points (n, 5, 3) around the FAWT hover point (CoM + 4 hubs) and velocities (n, 3)."""
    com = FAWT_HOVER_POINT_NED + 0.05 * rng.standard_normal((n, 3))
    hubs = 0.25 * np.array([[1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [1.0, -1.0, 0.0]])
    points = np.ascontiguousarray(com[:, None, :] + np.concatenate([np.zeros((1, 3)), hubs])[None])
    return points, 0.5 * rng.standard_normal((n, 3))


def _run(spec, n: int, restarts: dict[int, list[int]], same_step: bool, steps: int = 600):
    """Drive an n-row BatchWind and n one-row BatchWinds alike (the env's protocol); returns both (steps, n, 5, 3)
    series of wind samples and the restarted rows' first samples of the same-step mode."""
    batch = BatchWind(make_wind(spec), n)
    singles = [BatchWind(make_wind(spec), 1) for _ in range(n)]
    episode = [0] * n
    rng = np.random.default_rng(5)

    def reset(rows: list[int]) -> None:
        seeds = [_seed(r, episode[r]) for r in rows]
        batch.reset_rows(np.array(rows, dtype=np.intp), [s[0] for s in seeds], [s[1] for s in seeds])
        for r, (ent, ss) in zip(rows, seeds, strict=True):
            singles[r].reset_rows(np.array([0], dtype=np.intp), [ent], [ss])
            episode[r] += 1

    times = np.zeros(n)
    reset(list(range(n)))
    got, want, first_got, first_want = [], [], [], []
    pts, vel = _inputs(rng, n)
    for k in range(steps):
        rows = restarts.get(k, [])
        if rows and not same_step:  # next-step mode: the restarted rows step at time 0 with the others
            reset(rows)
            times[rows] = 0.0
        got.append(batch.step(times, DT, pts, vel))
        want.append(np.concatenate([s.step(times[i:i + 1], DT, pts[i:i + 1], vel[i:i + 1])
                                    for i, s in enumerate(singles)]))
        if rows and same_step:  # same-step mode: the restarted rows' first sample alone, the others untouched
            reset(rows)
            times[rows] = 0.0
            pts, vel = _inputs(rng, n)
            first_got.append(batch.first_step(DT, pts[rows], vel[rows]))
            first_want.append(np.concatenate([singles[r].step(np.zeros(1), DT, pts[r:r + 1], vel[r:r + 1])
                                              for r in rows]))
        else:
            pts, vel = _inputs(rng, n)
        times += DT
    return (np.array(got), np.array(want)), (first_got, first_want)


@pytest.mark.parametrize("same_step", [False, True], ids=["next_step", "same_step"])
@pytest.mark.parametrize("name", list(WINDS))
def test_each_row_is_the_row_alone(name: str, same_step: bool) -> None:
    # restarts at different steps, so the rows' blocks of normals (256 steps) run out at different steps too
    n = 5
    restarts = {3: [1], 9: [0, 3, 4], 10: [2], 17: [1, 2], 25: list(range(n)), 31: [4], 270: [0], 301: [1, 3],
                540: [2]}
    (got, want), (first_got, first_want) = _run(WINDS[name], n, restarts, same_step)
    np.testing.assert_array_equal(got, want)
    for fg, fw in zip(first_got, first_want, strict=True):
        np.testing.assert_array_equal(fg, fw)
    if name != "gust-1cos":  # a random wind: the rows differ from each other (not one stream copied)
        lateral = got[:, :, 0, 1]
        blowing = np.all(lateral != 0.0, axis=1)  # steps where every row's fans run (a schedule starts them off)
        assert blowing.sum() >= 10
        assert np.all(np.diff(lateral[blowing], axis=1) != 0.0)


@pytest.mark.parametrize("name", ["fawt-50", "dryden-light"])
def test_row_does_not_depend_on_the_batch_size(name: str) -> None:
    # the first reset alone: row 2 of a 3-row and of a 64-row batch, and the one-row batch with its seed
    rng = np.random.default_rng(1)
    pts, vel = _inputs(rng, 64)
    outs = []
    for n in (1, 3, 64):
        w = BatchWind(make_wind(WINDS[name]), n)
        seeds = [_seed(r, 0) for r in range(n)] if n > 1 else [_seed(2, 0)]
        w.reset_rows(np.arange(n), [s[0] for s in seeds], [s[1] for s in seeds])
        sl = slice(2, 3) if n > 1 else slice(0, 1)
        series = [w.step(np.zeros(n), DT, pts[:n] if n > 1 else pts[2:3], vel[:n] if n > 1 else vel[2:3])[sl]
                  for _ in range(300)]  # past one noise block (256 steps)
        outs.append(np.array(series))
    np.testing.assert_array_equal(outs[1], outs[0])
    np.testing.assert_array_equal(outs[2], outs[0])


@pytest.mark.parametrize("autoreset_mode", ["next_step", "same_step"])
@pytest.mark.parametrize("wind", ["fawt-50", {"name": "fawt-50", "on_time": 0.0, "spin_tau": 0.05}, "dryden-moderate"],
                         ids=["fawt-50", "fawt-schedule", "dryden-moderate"])
def test_batch_env_rows_have_their_single_env_wind(wind, autoreset_mode: str) -> None:
    # row 1 climbs out of its box and restarts while rows 0 and 2 hover: each row's wind is its single env's
    n, seed = 3, 11
    kw = dict(wind=wind, sensors="none", init_noise=0.5, episode_seconds=0.25, max_position_error=0.3,
              control_rate=100.0)
    batch = HoverBatchEnv(n, autoreset_mode=autoreset_mode, **kw)
    singles = [HoverEnv(**kw) for _ in range(n)]
    _, info_b = batch.reset(seed=seed)
    infos = [e.reset(seed=seed + i)[1] for i, e in enumerate(singles)]
    hover = batch.hover_action()[0]
    actions = np.tile(hover, (n, 1))
    actions[1] = 1.0  # full thrust: row 1 leaves its box and restarts
    restarts, done = 0, np.zeros(n, dtype=bool)
    for _ in range(60):
        _, _, term, trunc, info_b = batch.step(actions)
        for i, e in enumerate(singles):
            if done[i]:  # the single env's reset is the batch row's autoreset
                _, infos[i] = e.reset()
            else:
                _, _, t1, t2, infos[i] = e.step(actions[i])
                if (t1 or t2) and autoreset_mode == "same_step":
                    _, infos[i] = e.reset()
            for key, value in infos[i]["truth"].items():  # the wind, and the vehicle state it is sampled at
                np.testing.assert_array_equal(info_b["truth"][key][i], value,
                                              err_msg=f"row {i}'s truth[{key!r}] is not its single env's")
        ended = term | trunc
        restarts += int(ended[1])
        done = ended if autoreset_mode == "next_step" else np.zeros(n, dtype=bool)
    assert restarts >= 2  # row 1 restarted while the others flew
