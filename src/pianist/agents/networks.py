"""Flax networks of the agents: MLPs, a tanh-Gaussian actor, an ensemble of Q critics.

Shapes: observations (B, D), actions (B, A); an ensemble of N critics returns (N, B).
Initialisation as in the original training code: Xavier-uniform weights, zero biases.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import flax.linen as nn
import jax.numpy as jnp

ACTIVATIONS: dict[str, Callable[[jnp.ndarray], jnp.ndarray]] = {
    "gelu": nn.gelu,  # tanh approximation (flax's default); the NumPy actor matches it
    "relu": nn.relu,
    "tanh": jnp.tanh,
}


class MLP(nn.Module):
    """Dense layers; after each: dropout (if any), layer norm (if on), then the activation."""

    hidden_dims: Sequence[int]
    activation: str = "gelu"
    dropout: float = 0.0
    layer_norm: bool = False

    @nn.compact
    def __call__(self, x: jnp.ndarray, training: bool = False) -> jnp.ndarray:
        act = ACTIVATIONS[self.activation]
        for size in self.hidden_dims:
            x = nn.Dense(size, kernel_init=nn.initializers.xavier_uniform())(x)
            if self.dropout > 0:
                x = nn.Dropout(self.dropout, deterministic=not training)(x)
            if self.layer_norm:
                x = nn.LayerNorm()(x)
            x = act(x)
        return x


class Actor(nn.Module):
    """Observation (B, D) -> mean (B, A) and log std (B, A) of the pre-tanh Gaussian.

    ``zero_mean_init``: the mean head starts at zero weights, so the first policy's mean action
    is exactly 0 (for a residual policy: the planner's action). ``init_log_std``: the log-std
    head starts with zero weights and this bias, a state-independent std exp(init_log_std).
    """

    hidden_dims: Sequence[int]
    action_dim: int
    activation: str = "gelu"
    log_std_min: float = -20.0
    log_std_max: float = 2.0
    zero_mean_init: bool = False
    init_log_std: float | None = None

    @nn.compact
    def __call__(self, obs: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
        x = MLP(self.hidden_dims, self.activation)(obs)
        init = nn.initializers.xavier_uniform()
        zeros = nn.initializers.zeros
        mean = nn.Dense(
            self.action_dim, kernel_init=zeros if self.zero_mean_init else init, name="mean"
        )(x)
        if self.init_log_std is None:
            log_std = nn.Dense(self.action_dim, kernel_init=init, name="log_std")(x)
        else:
            log_std = nn.Dense(
                self.action_dim,
                kernel_init=zeros,
                bias_init=nn.initializers.constant(self.init_log_std),
                name="log_std",
            )(x)
        return mean, jnp.clip(log_std, self.log_std_min, self.log_std_max)


class Critic(nn.Module):
    """(obs (B, D), action (B, A)) -> Q (B,)."""

    hidden_dims: Sequence[int]
    activation: str = "gelu"
    dropout: float = 0.0
    layer_norm: bool = False

    @nn.compact
    def __call__(
        self, obs: jnp.ndarray, action: jnp.ndarray, training: bool = False
    ) -> jnp.ndarray:
        x = jnp.concatenate([obs, action], axis=-1)
        x = MLP(self.hidden_dims, self.activation, self.dropout, self.layer_norm)(x, training)
        q = nn.Dense(1, kernel_init=nn.initializers.xavier_uniform())(x)
        return q[..., 0]


class CriticEnsemble(nn.Module):
    """N independent critics (parameters stacked on a leading axis) -> Q (N, B)."""

    num: int
    hidden_dims: Sequence[int]
    activation: str = "gelu"
    dropout: float = 0.0
    layer_norm: bool = False

    @nn.compact
    def __call__(
        self, obs: jnp.ndarray, action: jnp.ndarray, training: bool = False
    ) -> jnp.ndarray:
        ensemble = nn.vmap(
            Critic,
            variable_axes={"params": 0},
            split_rngs={"params": True, "dropout": True},
            in_axes=None,
            out_axes=0,
            axis_size=self.num,
        )
        return ensemble(
            self.hidden_dims, self.activation, self.dropout, self.layer_norm, name="critics"
        )(obs, action, training)
