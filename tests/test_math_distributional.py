"""HuRi's math against independent computations: energy distance, distortions, IQR, SR(lambda) targets."""

import numpy as np
import pytest
import torch as th
from scipy import stats

from sb3_huri.common import (
    cvar_weights,
    distortion_weights,
    energy_distance,
    interpolated_quantile,
    interquartile_range,
    iqr_risk_level,
    sr_lambda_targets,
    wang_weights,
)


def pairwise_energy_distance(x: th.Tensor, y: th.Tensor) -> th.Tensor:
    """Eq. (4) written literally with all N x M pairs."""

    def mean_abs(a: th.Tensor, b: th.Tensor) -> th.Tensor:
        return (a[..., :, None] - b[..., None, :]).abs().mean(dim=(-1, -2))

    return 2 * mean_abs(x, y) - mean_abs(x, x) - mean_abs(y, y)


# --- energy distance ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("n", "m"), [(64, 64), (7, 3), (1, 5)])
def test_energy_distance_is_the_square_of_scipys(n, m):
    rng = np.random.default_rng(n * 100 + m)
    x, y = rng.normal(size=(5, n)), rng.normal(1.0, 2.0, size=(5, m))
    ours = energy_distance(th.as_tensor(x), th.as_tensor(y)).numpy()
    # scipy returns sqrt(2 E|X-Y| - E|X-X'| - E|Y-Y'|).
    reference = [stats.energy_distance(x[i], y[i]) ** 2 for i in range(5)]
    np.testing.assert_allclose(ours, reference, rtol=1e-10, atol=1e-12)


def test_energy_distance_gradients_match_the_pairwise_formula():
    x = th.randn(6, 16, dtype=th.float64, requires_grad=True)
    y = (3.0 * th.randn(6, 9, dtype=th.float64) + 1.0).requires_grad_()
    ours, reference = energy_distance(x, y), pairwise_energy_distance(x, y)
    th.testing.assert_close(ours, reference)
    for ours_grad, reference_grad in zip(
        th.autograd.grad(ours.sum(), (x, y)), th.autograd.grad(reference.sum(), (x, y)), strict=True
    ):
        th.testing.assert_close(ours_grad, reference_grad)


def test_energy_distance_is_zero_for_equal_sets_and_accurate_far_from_zero_in_float32():
    x = th.randn(4, 64)
    th.testing.assert_close(energy_distance(x, x[:, th.randperm(64)]), th.zeros(4), atol=1e-5, rtol=0)
    # Large returns: the result only depends on the differences.
    shifted = energy_distance(x + 1e4, x.flip(-1) * 1.5 + 1e4)
    th.testing.assert_close(shifted, energy_distance(x, x.flip(-1) * 1.5), atol=2e-3, rtol=1e-3)


# --- distortion weights ------------------------------------------------------------------------------


def test_wang_weights_for_beta_one_and_five_atoms():
    weights = wang_weights(th.tensor(1.0, dtype=th.float64), 5)
    np.testing.assert_allclose(weights.numpy(), [0.563, 0.209, 0.123, 0.072, 0.033], atol=1e-3)


def test_wang_weights_match_scipy_normal_and_sum_to_one():
    betas = np.array([-2.0, -0.7, 0.0, 0.3, 1.0, 1.9])
    levels = np.linspace(0, 1, 11)
    reference = np.diff(stats.norm.cdf(stats.norm.ppf(levels)[None] + betas[:, None]), axis=1)
    weights = wang_weights(th.as_tensor(betas), 10).numpy()
    np.testing.assert_allclose(weights, reference, atol=1e-12)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-12)
    assert (weights >= 0).all()


def test_wang_sign_convention_beta_positive_is_risk_averse():
    atoms = th.sort(th.randn(8, 32), dim=-1).values
    mean = atoms.mean(dim=-1)
    value = lambda beta: (wang_weights(th.full((8,), beta), 32) * atoms).sum(dim=-1)  # noqa: E731
    assert (value(1.0) < mean).all()
    assert (value(-1.0) > mean).all()
    th.testing.assert_close(value(0.0), mean)


def test_cvar_weights_by_hand():
    np.testing.assert_allclose(cvar_weights(th.tensor(0.5), 4).numpy(), [0.5, 0.5, 0.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(cvar_weights(th.tensor(0.5), 5).numpy(), [0.4, 0.4, 0.2, 0.0, 0.0], atol=1e-7)
    np.testing.assert_allclose(cvar_weights(th.tensor(1.0), 4).numpy(), [0.25] * 4, atol=1e-7)
    # Batched per-state levels: each row is a convex combination.
    weights = cvar_weights(th.tensor([0.1, 0.5, 1.0]), 64)
    th.testing.assert_close(weights.sum(dim=-1), th.ones(3))


def test_distortion_weights_dispatch_and_cvar_clipping():
    risk = th.tensor([0.5, 1.7])
    th.testing.assert_close(distortion_weights("wang", risk, 8), wang_weights(risk, 8))
    # A CVaR level above 1 (e.g. raised by the RND bonus) is the risk-neutral mean.
    th.testing.assert_close(distortion_weights("cvar", risk, 8)[1], th.full((8,), 1 / 8))
    with pytest.raises(ValueError, match="wang"):
        distortion_weights("exponential", risk, 8)


# --- quantiles and IQR -------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 5, 64])
@pytest.mark.parametrize("level", [0.0, 0.1, 0.25, 0.5, 0.75, 0.99, 1.0])
def test_interpolated_quantile_is_numpys_hazen_quantile(n, level):
    atoms = np.sort(np.random.default_rng(n).normal(size=(3, n)), axis=-1)
    ours = interpolated_quantile(th.as_tensor(atoms), level).numpy()
    np.testing.assert_allclose(ours, np.quantile(atoms, level, axis=-1, method="hazen"), atol=1e-12)


def test_interquartile_range_and_risk_levels():
    atoms = np.sort(np.random.default_rng(0).normal(scale=[[0.1], [0.5], [2.0]], size=(3, 64)), axis=-1)
    iqr = interquartile_range(th.as_tensor(atoms))
    reference = np.quantile(atoms, 0.75, axis=-1, method="hazen") - np.quantile(
        atoms, 0.25, axis=-1, method="hazen"
    )
    np.testing.assert_allclose(iqr.numpy(), reference, atol=1e-12)
    levels = iqr_risk_level(th.tensor([0.1, 0.3, 0.5, 0.7, 0.9]), (0.3, 0.7), (-1.0, 0.0, 1.0))
    np.testing.assert_array_equal(levels.numpy(), [-1.0, 0.0, 0.0, 0.0, 1.0])


# --- SR(lambda) targets ------------------------------------------------------------------------------


def _chain():
    """One env, 7 steps: a terminal on step 2 (s_3 starts a new episode), a time-out on step 4."""
    rng = np.random.default_rng(3)
    n_steps, n_atoms = 7, 4
    rewards = rng.normal(size=(n_steps, 1)).astype(np.float32)
    atoms = np.sort(rng.normal(size=(n_steps, 1, n_atoms)), axis=-1).astype(np.float32)
    episode_starts = np.zeros((n_steps, 1), dtype=np.float32)
    episode_starts[[0, 3, 5]] = 1.0
    bootstrap = np.zeros_like(atoms)
    bootstrap[4] = np.sort(rng.normal(size=(1, n_atoms)), axis=-1)  # final state of the truncated episode
    last_atoms = np.sort(rng.normal(size=(1, n_atoms)), axis=-1).astype(np.float32)
    return rewards, atoms, episode_starts, bootstrap, last_atoms


def test_sr_lambda_one_is_the_discounted_return_from_the_bootstrap():
    rewards, atoms, starts, bootstrap, last_atoms = _chain()
    gamma = 0.9
    targets = sr_lambda_targets(rewards, atoms, starts, last_atoms, np.zeros(1), gamma, 1.0, bootstrap)
    # Episodes: steps 0-2 (terminal), 3-4 (time-out: bootstrap from its last state), 5-6 (bootstrap from s_7).
    expected = np.zeros_like(atoms)
    for first, last, tail in [(0, 2, 0.0 * last_atoms), (3, 4, bootstrap[4]), (5, 6, last_atoms)]:
        for step in range(first, last + 1):
            discounted = sum(gamma ** (k - step) * rewards[k, 0] for k in range(step, last + 1))
            expected[step] = discounted + gamma ** (last + 1 - step) * tail
    np.testing.assert_allclose(targets, expected, rtol=1e-5, atol=1e-5)


def test_sr_lambda_zero_is_the_one_step_target():
    rewards, atoms, starts, bootstrap, last_atoms = _chain()
    gamma = 0.9
    targets = sr_lambda_targets(rewards, atoms, starts, last_atoms, np.zeros(1), gamma, 0.0, bootstrap)
    next_atoms = {
        0: atoms[1],
        1: atoms[2],
        2: 0 * atoms[0],
        3: atoms[4],
        4: bootstrap[4],
        5: atoms[6],
        6: last_atoms,
    }
    for step, following in next_atoms.items():
        np.testing.assert_allclose(targets[step], rewards[step] + gamma * following, rtol=1e-6, atol=1e-6)


def test_sr_lambda_mixture_has_the_td_lambda_return_as_its_mean():
    """Averaged over many atoms, the SR(lambda) target is the TD(lambda) return of the atom means."""
    rng = np.random.default_rng(0)
    n_steps, n_envs, n_atoms, gamma, lam = 12, 2, 20_000, 0.95, 0.6
    rewards = rng.normal(size=(n_steps, n_envs))
    atoms = rng.normal(loc=rng.normal(size=(n_steps, n_envs, 1)), size=(n_steps, n_envs, n_atoms))
    starts = (rng.random((n_steps, n_envs)) < 0.15).astype(np.float64)
    last_atoms = rng.normal(size=(n_envs, n_atoms))
    dones = np.array([0.0, 1.0])
    targets = sr_lambda_targets(rewards, atoms, starts, last_atoms, dones, gamma, lam, rng=rng)
    # TD(lambda) returns of the means: G_t = r_t + gamma (1 - d) ((1 - lam) V_{t+1} + lam G_{t+1}).
    values, returns = atoms.mean(-1), np.zeros((n_steps, n_envs))
    next_return, next_value = last_atoms.mean(-1), last_atoms.mean(-1)
    for step in reversed(range(n_steps)):
        continues = 1.0 - (dones if step == n_steps - 1 else starts[step + 1])
        returns[step] = rewards[step] + gamma * continues * ((1 - lam) * next_value + lam * next_return)
        next_return, next_value = returns[step], values[step]
    np.testing.assert_allclose(targets.mean(-1), returns, atol=0.05)
