"""1D quasi-static Galerkin model of an MPM Tait-water pool at rest.

Unknowns: nodal displacements u_i of all nodes whose quadratic B-spline support
contains a particle, plus a Lagrange multiplier for the floor constraint u(0)=0
(sum_i u_i w_i(0) = 0, reaction lam*w_i(0)).
Particle strain e_p = sum_i u_i B_i(Y_p), J_p = exp(e_p) (or 1+e_p),
p_p = K/gam (J^-gam - 1). Equilibrium at every node with mass:
  sum_p V_p p_p S_i(y_p) - g sum_p m_p w_i(y_p) + lam w_i(0) = 0
B = gradient used for the strain (velocity gradient), S = gradient used for the force.
APIC: B=S=w'.  MLS: B=S=G = 4/h^2 w_i(x)(x_i-x).
"""
import numpy as np

rho, K, gam, g, H, h = 1000.0, 4e5, 7.0, 9.81, 0.2, 0.0125
NL = 16


def wq(r):
    a = np.abs(r)
    return np.where(a < 0.5, 0.75 - a * a, np.where(a < 1.5, 0.5 * (1.5 - a) ** 2, 0.0))


def dwq(r):
    a = np.abs(r)
    return np.where(a < 0.5, -2 * r, np.where(a < 1.5, -np.sign(r) * (1.5 - a), 0.0))


def press(J):
    return K / gam * (J ** -gam - 1.0)


def dpress(J):
    return -K * J ** (-gam - 1.0)


def setup(ppa, off):
    dx = h / ppa
    Y = (np.arange(NL * ppa) + 0.5) * dx
    o = off * h
    imin = int(np.floor((Y.min() - 1.5 * h - o) / h)) - 1
    imax = int(np.ceil((Y.max() + 1.5 * h - o) / h)) + 1
    yi = o + np.arange(imin, imax + 1) * h
    W = wq((Y[:, None] - yi[None, :]) / h)
    keep = W.sum(0) > 0
    return Y, yi[keep], dx


def mats(x, yi, kind):
    r = (x[:, None] - yi[None, :]) / h
    W = wq(r)
    if kind == 'apic':
        Bm = dwq(r) / h
    else:
        Bm = W * (yi[None, :] - x[:, None]) * 4.0 / h ** 2
    return W, Bm


def exact_p(Y):
    return rho * g * (H - Y)


def layer_err(Y, p):
    lay = np.minimum((Y / h).astype(int), NL - 1)
    out = np.zeros(NL)
    for j in range(NL):
        ex = rho * g * (H - (j + 0.5) * h)
        out[j] = (p[lay == j].mean() - ex) / ex
    return out


def solve(ppa, off, kind='apic', strain='log', geom=False, floor='lagrange',
          force_kind=None, pmap=None, forcemod=None, it=30, reg=0.0):
    """Newton solve of the static equilibrium.
    pmap(J, ctx) -> pressure used in the force (and reported), default Tait.
    forcemod: optional function modifying (W, S, V) used in the force.
    Returns dict with Y, p (reported particle pressure), layer errors."""
    Y, yi, dx = setup(ppa, off)
    V0 = dx
    m = rho * V0
    n = len(yi)
    W0, B0 = mats(Y, yi, kind)
    wfl = wq((0.0 - yi) / h)
    fk = force_kind or kind
    fixed = np.zeros(n, bool)
    if floor == 'dirichlet':
        fixed = yi <= 1e-12
    u = np.zeros(n)
    lam = 0.0
    free = ~fixed

    def resid(u, lam):
        e = B0 @ u
        J = np.exp(e) if strain == 'log' else 1.0 + e
        x = Y + (W0 @ u if geom else 0.0)
        W, S = mats(x, yi, fk)
        V = V0 * J
        pp = press(J) if pmap is None else pmap(J, dict(W=W0, V0=V0, Y=Y))
        Wf, Sf, Vf = (W, S, V) if forcemod is None else forcemod(W, S, V, Y)
        R = Sf.T @ (Vf * pp) - g * (W.T @ np.full(len(Y), m))
        if floor == 'lagrange':
            R = R + lam * wfl
        return R, pp, J

    # Newton with finite-difference Jacobian (tiny system)
    nun = n + (1 if floor == 'lagrange' else 0)
    z = np.zeros(nun)

    def F(z):
        u = z[:n].copy(); u[fixed] = 0
        lam = z[n] if floor == 'lagrange' else 0.0
        R, pp, J = resid(u, lam)
        R = R.copy(); R[fixed] = z[:n][fixed]
        if floor == 'lagrange':
            R = np.append(R, wfl @ u / h)
        return R

    for k in range(it):
        R = F(z)
        Jm = np.zeros((nun, nun))
        eps = 1e-9
        for j in range(nun):
            dz = np.zeros(nun); dz[j] = eps * (1 if j < n else 1e5)
            Jm[:, j] = (F(z + dz) - R) / dz[j]
        if reg > 0:
            Jm[:n, :n] += reg * np.eye(n) * np.abs(Jm).max()
        dzs = np.linalg.lstsq(Jm, -R, rcond=1e-11)[0]
        z = z + dzs
        if np.abs(dzs[:n]).max() < 1e-16:
            break
    u = z[:n].copy(); u[fixed] = 0
    lam = z[n] if floor == 'lagrange' else 0.0
    R, pp, J = resid(u, lam)
    cond = np.linalg.cond(Jm)
    return dict(Y=Y, yi=yi, u=u, p=pp, J=J, err=layer_err(Y, pp), res=np.abs(R[free]).max(),
                cond=cond, mass=W0.sum(0) * m)


if __name__ == '__main__':
    import sys
    for kind in ['apic', 'mls']:
        for ppa in [2, 3]:
            tops, worst = [], []
            for k in range(8):
                r = solve(ppa, k / 8, kind)
                tops.append(r['err'][-1] * 100)
                worst.append(np.abs(r['err'][2:]).max() * 100)
            print(kind, ppa, 'top %:', ' '.join('%6.2f' % t for t in tops))
            print(kind, ppa, 'max|err| layers 2..15 %:', ' '.join('%6.2f' % t for t in worst))
