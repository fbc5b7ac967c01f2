"""fawtgym.core.normals: the numbers and the generator state of ``rng.standard_normal(shape)``, whichever routine
draws them (NumPy's fill below COMPILED_MIN numbers, numba's Generator method above)."""

from __future__ import annotations

import numpy as np
import pytest

from fawtgym.core.normals import COMPILED_MIN, standard_normals


def _same_state(a: object, b: object) -> bool:
    """Bit generator states (nested dicts holding ints and arrays) equal."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same_state(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    return a == b


@pytest.mark.parametrize("bit_generator", [np.random.PCG64, np.random.SFC64, np.random.MT19937, np.random.Philox])
@pytest.mark.parametrize("shape", [(1, 21), (3,), (COMPILED_MIN - 1,), (COMPILED_MIN,), (512, 21), (256, 5), (0, 21),
                                   (40_000, 5)])
def test_same_numbers_and_state_as_numpy(bit_generator: type, shape: tuple[int, ...]) -> None:
    ours, theirs = np.random.Generator(bit_generator(11)), np.random.Generator(bit_generator(11))
    for _ in range(3):  # consecutive draws read the stream on from where the last one left it
        got = standard_normals(ours, shape)
        want = theirs.standard_normal(shape)
        assert got.shape == want.shape and got.dtype == np.float64 and got.flags.c_contiguous
        np.testing.assert_array_equal(got, want)
    assert _same_state(ours.bit_generator.state, theirs.bit_generator.state)
    # and the generator goes on from the same state when NumPy draws from it next
    np.testing.assert_array_equal(ours.standard_normal(7), theirs.standard_normal(7))


def test_the_tail_of_the_ziggurat_too() -> None:
    """Enough numbers (~5 million) that the ziggurat's rare paths (the wedges and the tail beyond 3.44) are taken."""
    ours, theirs = np.random.default_rng(3), np.random.default_rng(3)
    got, want = standard_normals(ours, (1_000_000, 5)), theirs.standard_normal((1_000_000, 5))
    assert np.abs(want).max() > 4.5  # the tail was sampled
    np.testing.assert_array_equal(got, want)


def test_fresh_arrays() -> None:
    rng = np.random.default_rng(0)
    a, b = standard_normals(rng, (COMPILED_MIN,)), standard_normals(rng, (COMPILED_MIN,))
    assert not np.shares_memory(a, b) and not np.array_equal(a, b)


def test_the_gust_block_only_chunks_each_fields_stream() -> None:
    """A Dryden field reads the same normals whatever its block (the block is chosen by N: noise_block)."""
    from fawtgym.envs.wind.dryden import DrydenParams
    from fawtgym.envs.wind.dryden_process import BLOCK_MAX, BLOCK_MIN, DrydenProcess, noise_block

    assert noise_block(1, 5) == noise_block(64, 5) == noise_block(10**6, 5) == BLOCK_MIN  # a few fields, or many
    assert BLOCK_MIN < noise_block(512, 5) < BLOCK_MAX and 512 * noise_block(512, 5) * 5 * 8 <= 32 * 2**20
    params = DrydenParams(sigma=(1.0, 1.0, 1.0), length=(0.02, 0.02, 0.02), form="8785c", span=0.5)
    runs = []
    for block in (None, 3, 256):
        proc = DrydenProcess(params, block=block)
        proc.reset(4, seed=7)
        runs.append(np.stack([proc.step(0.005, np.array([8.0, 7.0, 9.0, 8.5])) for _ in range(20)]))
    assert proc.block == 256
    np.testing.assert_array_equal(runs[0], runs[1])
    np.testing.assert_array_equal(runs[0], runs[2])
