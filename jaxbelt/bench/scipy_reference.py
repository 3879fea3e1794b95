"""A numpy + scipy.sparse implementation of the same 2D step (SuperLU every step, vectorised
assembly): what a careful user would write instead of jaxbelt. Used by ``jaxbelt bench``
(:mod:`jaxbelt.bench.baselines`) and ``benchmarks/solver_2d.py``; needs SciPy (a dev dependency,
imported only by ``jaxbelt bench``).

It takes the built model's data (element blocks, roller kinematics, masses) from jaxbelt's
public ``BeltModel`` fields and re-implements assembly, solve and transport (shift rule with the
roller-relative correction) in numpy/scipy.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..assembly import roller_surface_displacement


class ScipyBelt:
    """The step of ``model`` with time step ``dt`` (s), in numpy + SciPy."""

    def __init__(self, model, dt: float):
        g = lambda a: np.asarray(a)  # noqa: E731
        self.m = model
        self.dt = float(dt)
        self.Kd, self.Kl, self.Ku = g(model.K_diag), g(model.K_lower), g(model.K_upper)
        self.R0, self.Rdz = g(model.R), g(model.R_dz)
        self.con, self.dyn = g(model.is_constraint), g(model.dynamic)
        self.n, self.b, self.q = self.R0.shape
        self.f0, self.Q, self.Mr = g(model.f0), g(model.Q_ext), g(model.M_roller)
        self.chi_s, self.omega, self.is_az = g(model.chi_static), g(model.omega), g(model.is_az)
        self.ell, self.node_roller = g(model.ell), g(model.node_roller)
        # static surface offset (exact minus linear), constant for a run
        self.offset = g(roller_surface_displacement(model, model.chi_static, model.R)) - np.einsum(
            "nbq,q->nb", self.R0, self.chi_s)
        n, b = self.n, self.b
        i = np.arange(n)
        rows, cols = [], []
        for blk, cshift in ((0, 0), (1, -1), (2, 1)):
            r = (i[:, None, None] * b + np.arange(b)[None, :, None]) * np.ones((1, 1, b), int)
            c = (((i + cshift) % n)[:, None, None] * b + np.arange(b)[None, None, :]) * np.ones((1, b, 1), int)
            rows.append(r.ravel()); cols.append(c.ravel())
        self.rows, self.cols = np.concatenate(rows), np.concatenate(cols)

    def R(self, u):
        lever = np.zeros_like(u)
        lever[:, 0::2] = u[:, 1::2]
        return self.R0 + self.Rdz * lever[:, :, None]

    def masses(self, m_e):
        col = m_e + np.roll(m_e, 1, axis=0)
        z = np.zeros((m_e.shape[0], 1))
        return np.repeat(0.25 * (np.concatenate([col, z], 1) + np.concatenate([z, col], 1)), 2, axis=1)

    def matrices(self, m_e, R):
        n, b, q = self.n, self.b, self.q
        con = self.con[:, :, None]
        eye = np.eye(b)[None]
        Kd = np.where(con, eye, self.Kd); Kl = np.where(con, 0, self.Kl); Ku = np.where(con, 0, self.Ku)
        m = self.masses(m_e)
        dt2 = self.dt**2
        Ad = dt2 * Kd + np.where(con, 0.0, m[:, :, None] * eye)
        belt = sp.coo_matrix((np.concatenate([Ad.ravel(), dt2 * Kl.ravel(), dt2 * Ku.ravel()]), (self.rows, self.cols)),
                             shape=(n * b, n * b))
        C = np.where(con, -R, 0.0).reshape(n * b, q) * dt2
        Rt = np.swapaxes(R, 1, 2)
        DK = Rt @ self.Kd + np.swapaxes(np.roll(R, 1, 0), 1, 2) @ np.roll(self.Ku, 1, 0) + \
            np.swapaxes(np.roll(R, -1, 0), 1, 2) @ np.roll(self.Kl, -1, 0)
        D = np.where(self.dyn[None, :, None], dt2 * DK + Rt * m[:, None, :], 0.0)
        D = D.transpose(1, 0, 2).reshape(q, n * b)
        E = np.diag(np.where(self.dyn, self.Mr, dt2))
        A = sp.bmat([[belt, sp.csr_matrix(C)], [sp.csr_matrix(D), sp.csr_matrix(E)]], format="csc")
        return A

    def K_apply(self, R, xb, xr):
        Kf = np.einsum("nij,nj->ni", self.Kd, xb) + np.einsum("nij,nj->ni", self.Kl, np.roll(xb, 1, 0)) + \
            np.einsum("nij,nj->ni", self.Ku, np.roll(xb, -1, 0))
        kb = np.where(self.con, xb - np.einsum("nbq,q->nb", R, xr), Kf)
        kr = np.where(self.dyn, np.einsum("nbq,nb->q", R, Kf), xr)
        return kb, kr

    def equilibrated(self, A, permc_spec="COLAMD"):
        """``(scale, SuperLU factor of diag(scale) A)``: rows scaled to unit max-norm (as jaxbelt's
        row equilibration; the rows differ by ~1e8 in scale, constraint rows being Δt² × unit
        coefficients, and SuperLU's threshold pivoting does not make up for it)."""
        scale = 1.0 / abs(A).max(axis=1).toarray().ravel()
        return scale, spla.splu((sp.diags(scale) @ A).tocsc(), permc_spec=permc_spec)

    def kept_factor(self, u, m_e, permc_spec="COLAMD"):
        """The factor of the first step's matrix, for :meth:`step` ``(kept=...)`` (factor once)."""
        return self.equilibrated(self.matrices(m_e, self.R(u)), permc_spec)

    def step(self, u, ud, chi, chid, m_e, permc_spec="COLAMD", kept=None):
        """One step: assemble, factor and solve (``kept=None``), or solve with a kept factor
        (``kept`` from :meth:`kept_factor`, no assembly: jaxbelt's reuse mode without refinement),
        then the transport."""
        dt = self.dt
        R = self.R(u)
        Fb = np.where(self.con, u - np.einsum("nbq,q->nb", R, chi), -self.f0)
        Fr = np.where(self.dyn, self.Q - np.einsum("nbq,nb->q", R, self.f0),
                      self.chi_s + np.where(self.is_az, chi, 0.0) + self.omega * dt)
        kb, kr = self.K_apply(R, u + dt * ud, chi + dt * chid)
        rhs = np.concatenate([(Fb - kb).ravel(), Fr - kr])
        scale, lu = kept if kept is not None else self.equilibrated(self.matrices(m_e, R), permc_spec)
        acc = lu.solve(rhs * scale)
        ab, ar = acc[: self.n * self.b].reshape(self.n, self.b), acc[self.n * self.b:]
        ud, chid = ud + dt * ab, chid + dt * ar
        u, chi = u + dt * ud, chi + dt * chid
        return self.transport(u, ud, chi, chid, m_e)

    def transport(self, u, ud, chi, chid, m_e):
        ux = u[:, 0::2]
        s = ux.mean()
        ell = self.ell[:, None]
        fwd = s >= 0
        a_x = np.full_like(ux, s / (np.roll(ell, 1, 0) if fwd else ell)[:, :1]) if fwd else \
            np.full_like(ux, -s) / ell
        a = np.stack([a_x, np.zeros_like(a_x)], 2).reshape(u.shape)
        up = (lambda f: np.roll(f, 1, 0)) if fwd else (lambda f: np.roll(f, -1, 0))
        r = np.einsum("nbq,q->nb", self.R(u), chi) + self.offset
        same = ((up(self.node_roller) == self.node_roller) & (self.node_roller >= 0))[:, None]
        u_new = a * up(u) + (1 - a) * u + np.where(same, a * (r - up(r)), 0.0)
        u_new[:, 0::2] -= s
        ud_new = a * up(ud) + (1 - a) * ud
        flux = a_x[:, :1] * (np.roll(m_e, 1, 0) if fwd else -m_e)
        m_new = m_e + flux - np.roll(flux, -1, 0)
        chi = np.where(self.is_az, 0.0, chi)
        return u_new, ud_new, chi, chid, m_new
