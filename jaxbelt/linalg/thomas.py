"""Block Thomas elimination of a block-tridiagonal matrix, and its sweeps rearranged along the
chains of dependent blocks that the belt's roller columns cut the interior into
(:class:`ChainedThomasFactors`). The interior solver of :mod:`jaxbelt.linalg.bordered` on a CPU
(the sequential ``lax.scan`` there; block cyclic reduction, :mod:`jaxbelt.linalg.cyclic_reduction`,
on accelerators)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax


class ThomasFactors(eqx.Module):
    """Block Thomas factors: inverse pivot blocks, ``Ĉ = den⁻¹ U`` and the sub-diagonal blocks."""

    inv: jax.Array
    C_hat: jax.Array
    L: jax.Array


def thomas_factor(diag, lower, upper, rhs=None):
    """Block Thomas factors; with ``rhs`` (m, b, k) also solves for it in the same sweep and
    returns ``(factors, solution)`` (one scan instead of two for the border columns)."""
    b = diag.shape[1]
    eye = jnp.eye(b, dtype=diag.dtype)
    lower = lower.at[0].set(0.0)
    k = 0 if rhs is None else rhs.shape[2]
    r = jnp.zeros((diag.shape[0], b, 0), diag.dtype) if rhs is None else rhs

    def forward(carry, blk):
        c_prev, y_prev = carry
        a, l, u, rr = blk
        inv = jnp.linalg.solve(a - l @ c_prev, eye)
        c, y = inv @ u, inv @ (rr - l @ y_prev)
        return (c, y), (inv, c, y)

    init = (jnp.zeros((b, b), diag.dtype), jnp.zeros((b, k), diag.dtype))
    _, (inv, C_hat, ys) = lax.scan(forward, init, (diag, lower, upper, r))
    F = ThomasFactors(inv, C_hat, lower)
    if rhs is None:
        return F

    def backward(x_next, blk):
        c, y = blk
        x = y - c @ x_next
        return x, x

    _, xs = lax.scan(backward, jnp.zeros((b, k), diag.dtype), (C_hat, ys), reverse=True)
    return F, xs


def thomas_apply(F: ThomasFactors, rhs):
    """Forward sweep ``y_i = den_i⁻¹ (r_i - L_i y_{i-1})``, backward ``x_i = y_i - Ĉ_i x_{i+1}``."""

    def forward(y_prev, blk):
        inv_i, l, r = blk
        y = inv_i @ (r - l @ y_prev)
        return y, y

    _, ys = lax.scan(forward, jnp.zeros_like(rhs[0]), (F.inv, F.L, rhs))

    def backward(x_next, blk):
        c, y = blk
        x = y - c @ x_next
        return x, x

    _, xs = lax.scan(backward, jnp.zeros_like(ys[0]), (F.C_hat, ys), reverse=True)
    return xs


class ChainedThomasFactors(eqx.Module):
    """Block Thomas factors rearranged along their chains of dependent blocks.

    A block ``i`` whose couplings ``L_i`` and ``U_i`` both vanish breaks the sweeps' chain of
    dependencies: its forward value does not need block ``i - 1``'s and its backward value does
    not need block ``i + 1``'s (``Ĉ_i = 0``). The belt's roller columns are such blocks — their
    rows are no-slip constraints, coupled only to the roller unknowns — so the interior falls
    apart into one chain per free span (each led, forward, by the roller column before it and,
    backward, by the one after it) and single roller columns. Both sweeps then run all chains at
    once, as one batched scan as long as the longest span, and the single blocks as one batched
    product: on ``three-roller-t72`` 37 dependent steps per sweep instead of 103 — the same
    arithmetic, ~35 % less time on a CPU, where the chain's latency sets the pace. Built by
    :func:`chain_thomas` from static break positions; the result equals :func:`thomas_apply`'s
    (``tests/test_kept_interior.py``).

    The forward sweep ``y_i = den_i⁻¹ (r_i - L_i y_{i-1})`` is kept as ``y_i = g_i - P_i y_{i-1}``
    with ``g_i = den_i⁻¹ r_i`` (all blocks at once, one batched product outside the scan) and
    ``P_i = den_i⁻¹ L_i`` (formed once with the factors): one dependent block product per step
    instead of two. Blocks are moved between the chains' and the natural order by gathers
    with static index tables (a gather's transpose is the scatter-add reverse mode needs; a
    scatter in the forward pass is slow on a CPU). Reuse step of ``three-roller-t72``: the
    interior apply 0.26 → 0.20 ms on this 2-core CPU.

    **Fields:** forward chains ``f_inv``, ``f_P`` (steps, chains, b, b); single blocks ``s_inv``;
    backward chains ``b_C`` (steps, chains, b, b); ``layout`` the static index tables."""

    f_inv: jax.Array
    f_P: jax.Array
    s_inv: jax.Array
    b_C: jax.Array
    layout: tuple = eqx.field(static=True)  # (f_idx, singles, b_idx, m): tuples of block indices, m = pad index


def _chains(m: int, breaks, reverse: bool):
    order = range(m - 1, -1, -1) if reverse else range(m)
    out, cur = [], []
    for i in order:
        if breaks[i] and cur:
            out.append(cur)
            cur = []
        cur.append(i)
    out.append(cur)
    return out


def _pad_chains(chains, m):
    n_steps = max(len(c) for c in chains)
    return tuple(tuple(c[t] if t < len(c) else m for c in chains) for t in range(n_steps))


def chain_thomas(F: ThomasFactors, breaks) -> ChainedThomasFactors:
    """Rearrange ``F`` along its chains (:class:`ChainedThomasFactors`). ``breaks`` (m,) static
    booleans: ``True`` where the block's ``L_i`` and ``U_i`` are zero (the caller's guarantee;
    e.g. the belt's roller columns)."""
    m = F.inv.shape[0]
    breaks = [bool(x) for x in breaks]
    fw = _chains(m, breaks, reverse=False)
    singles = tuple(c[0] for c in fw if len(c) == 1)
    fw = [c for c in fw if len(c) > 1] or [[m]]
    bw = [c for c in _chains(m, breaks, reverse=True) if len(c) > 1] or [[m]]
    f_idx, b_idx = _pad_chains(fw, m), _pad_chains(bw, m)
    pad = lambda a: jnp.concatenate([a, jnp.zeros_like(a[:1])], axis=0)  # noqa: E731  index m: a zero block
    inv, L, C = pad(F.inv), pad(F.L), pad(F.C_hat)
    fi, bi = np.asarray(f_idx), np.asarray(b_idx)
    f_inv = inv[fi]
    return ChainedThomasFactors(f_inv, f_inv @ L[fi], inv[np.asarray(singles, int)], C[bi], (f_idx, singles, b_idx, m))


def _chain_gathers(layout):
    """Static gather tables of a chained layout: ``fwd`` takes the natural order out of
    ``concat(forward chains (flattened), single blocks, one zero block)``; ``bwd`` takes it out of
    ``concat(backward chains (flattened), forward values)`` — a block in no backward chain keeps
    its forward value."""
    f_idx, singles, b_idx, m = layout
    fi, bi = np.asarray(f_idx).reshape(-1), np.asarray(b_idx).reshape(-1)
    fwd = np.full(m + 1, fi.size + len(singles))  # the padding index m: the zero block
    real = fi < m
    fwd[fi[real]] = np.flatnonzero(real)
    fwd[np.asarray(singles, int)] = fi.size + np.arange(len(singles))
    bwd = np.arange(m) + bi.size
    real = bi < m
    bwd[bi[real]] = np.flatnonzero(real)
    return fwd, bwd


def chained_thomas_apply(F: ChainedThomasFactors, rhs):
    """:func:`thomas_apply` along the chains; ``rhs`` (m, b, k)."""
    f_idx, singles, b_idx, m = F.layout
    fi, si, bi = np.asarray(f_idx), np.asarray(singles, int), np.asarray(b_idx)
    fwd, bwd = _chain_gathers(F.layout)
    r = jnp.concatenate([rhs, jnp.zeros_like(rhs[:1])], axis=0)
    g = F.f_inv @ r[fi]  # den⁻¹ r of every chained block at once

    def forward(y_prev, blk):
        p, gg = blk
        y = gg - p @ y_prev
        return y, y

    _, ys = lax.scan(forward, jnp.zeros((fi.shape[1],) + rhs.shape[1:], rhs.dtype), (F.f_P, g))
    tail = rhs.shape[1:]
    y = jnp.concatenate([ys.reshape((-1,) + tail), F.s_inv @ r[si], jnp.zeros_like(rhs[:1])])[fwd]  # (m + 1, b, k)

    def backward(x_next, blk):
        c, yy = blk
        x = yy - c @ x_next
        return x, x

    _, xs = lax.scan(backward, jnp.zeros((bi.shape[1],) + tail, rhs.dtype), (F.b_C, y[bi]))
    return jnp.concatenate([xs.reshape((-1,) + tail), y[:m]])[bwd]
