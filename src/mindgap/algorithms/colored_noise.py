"""Temporally correlated ("coloured") Gaussian noise for exploration (Eberhard et al. 2023).

SAC samples a fresh, independent Gaussian ε at every step (white noise): the agent jitters
around where its policy's mean takes it and rarely travels far in one direction. Coloured
noise keeps the same marginal distribution, N(0, 1) per step, but correlates steps with a
power spectrum ∝ 1/f^β: β = 0 is white noise, β = 1 pink (the default Eberhard et al.
recommend for off-policy RL), β = 2 red (Brownian-like). One sequence is drawn per episode
and ε_t replaces the white ε in ``tanh(μ + σ ε_t)``; the SAC update is unchanged.

The generator is the spectral method of Timmer & König (1995), as in the ``colorednoise``
package: random Fourier coefficients with amplitude f^(−β/2), an inverse real FFT, and a
division by the exact standard deviation of the result. It is written here in JAX (about
ten lines) so that it runs inside the jitted training loop; no JAX library offers it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def colored_noise(key: jax.Array, beta: float, length: int, dim: int) -> jax.Array:
    """``dim`` independent unit-variance Gaussian sequences with spectrum ∝ 1/f^β. → [length, dim].

    The lowest frequency 1/length stands in for f = 0, so the sequence's mean stays finite
    (and, for β > 0, carries most of the power: the whole episode leans one way).
    """
    if length < 2:
        raise ValueError(f"a coloured noise sequence needs at least 2 steps, got {length}")
    f = jnp.fft.rfftfreq(length)
    f = f.at[0].set(1.0 / length)
    amp = f ** (-beta / 2.0)
    k_re, k_im = jax.random.split(key)
    re = jax.random.normal(k_re, (dim, f.shape[0]))
    im = jax.random.normal(k_im, (dim, f.shape[0]))
    # The f = 0 coefficient (and f = 1/2 for an even length) of a real signal is real.
    real_only = jnp.zeros(f.shape[0], bool).at[0].set(True)
    if length % 2 == 0:
        real_only = real_only.at[-1].set(True)
    im = jnp.where(real_only, 0.0, im)
    x = jnp.fft.irfft(amp * (re + 1j * im), n=length, axis=-1)
    # Var x_t = (Σ_real-only amp² + 4 Σ_others amp²) / length², the same at every t: a complex
    # coefficient and its conjugate partner add 2 amp (re cos − im sin), of variance 4 amp².
    weight = jnp.where(real_only, 1.0, 4.0)
    std = jnp.sqrt(jnp.sum(weight * amp**2)) / length
    return (x / std).T
