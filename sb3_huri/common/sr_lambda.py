"""SR(lambda) target distributions for a quantile critic (GMAC, Nam et al. 2021; HuRi Algorithm 2)."""

import numpy as np


def sr_lambda_targets(
    rewards: np.ndarray,
    atoms: np.ndarray,
    episode_starts: np.ndarray,
    last_atoms: np.ndarray,
    last_dones: np.ndarray,
    gamma: float,
    sr_lambda: float,
    bootstrap_atoms: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """Target atoms ``T Z(s_t)`` built backwards through a rollout.

    ``target_t = r_t + gamma * (carry_{t+1} if s_{t+1} continues the episode else bootstrap_t)``, and the
    carry handed to step ``t - 1`` keeps each atom of ``target_t`` with probability ``lambda``, otherwise it
    takes the same-index atom of the current estimate ``Z(s_t)``. This is a sample of the lambda-mixture
    of n-step return distributions: ``lambda = 1`` gives the Monte-Carlo return distribution bootstrapped
    from the last state, ``lambda = 0`` the one-step target ``r_t + gamma Z(s_{t+1})``.
    Terminal steps do not bootstrap; time-outs bootstrap from the final state's atoms (``bootstrap_atoms``).

    :param rewards: shape ``(T, E)``
    :param atoms: atoms of ``Z(s_t)``, shape ``(T, E, N)``
    :param episode_starts: whether ``s_t`` starts an episode, shape ``(T, E)`` (SB3's convention)
    :param last_atoms: atoms of ``Z(s_T)`` for the state after the rollout, shape ``(E, N)``
    :param last_dones: whether the episode ended on the last step, shape ``(E,)``
    :param gamma: discount factor
    :param sr_lambda: mixing parameter in ``[0, 1]``
    :param bootstrap_atoms: atoms of the final state of episodes truncated at step ``t`` (zeros elsewhere),
        shape ``(T, E, N)``; ``None`` when no episode was truncated
    :param rng: random generator for the atom mixing when ``0 < lambda < 1`` (a fresh unseeded one if omitted)
    :return: target atoms, shape ``(T, E, N)``
    """
    n_steps = rewards.shape[0]
    targets = np.empty_like(atoms)
    carry = last_atoms
    rng = rng if rng is not None else np.random.default_rng()
    for step in reversed(range(n_steps)):
        ends = last_dones if step == n_steps - 1 else episode_starts[step + 1]
        next_atoms = (1.0 - ends)[:, None] * carry
        if bootstrap_atoms is not None:
            next_atoms = next_atoms + bootstrap_atoms[step]
        targets[step] = rewards[step][:, None] + gamma * next_atoms
        if sr_lambda >= 1.0:
            carry = targets[step]
        elif sr_lambda <= 0.0:
            carry = atoms[step]
        else:
            carry = np.where(rng.random(atoms[step].shape) < sr_lambda, targets[step], atoms[step])
    return targets
