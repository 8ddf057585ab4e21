"""General static solver + candidate schemes (1D column, engine offset convention j).

A scheme is a function scheme(x, yi, dx) -> dict(
    fint = f(u) -> (internal force on nodes (upward +), reported particle pressure),
    load = gravity load vector (>0 means downward weight),
    wmass = nodal mass weights (for 'active' nodes), S0 = force operator for the floor ghost weights)
Equilibrium: fint(u) - load + lam c = 0, sum_i w_i(0) u_i = 0.
"""
import numpy as np
import lin
from lin import rho, K, gam, g, H, h, NL, wq, dwq, press, layer_err, wint


def d2wq(r):
    a = np.abs(r)
    return np.where(a < 0.5, -2.0, np.where(a < 1.5, 1.0, 0.0))


def _c(dx):
    dx = np.asarray(dx, float)
    return dx[:, None] if dx.ndim == 1 else dx


def wbar(x, yi, dx):          # particle-domain mean of w
    dx = _c(dx)
    return (wint((x[:, None] + dx / 2 - yi[None, :]) / h) - wint((x[:, None] - dx / 2 - yi[None, :]) / h)) * h / dx


def sbar(x, yi, dx):          # particle-domain mean of w'
    dx = _c(dx)
    return (wq((x[:, None] + dx / 2 - yi[None, :]) / h) - wq((x[:, None] - dx / 2 - yi[None, :]) / h)) / dx


def hbar(x, yi, dx):          # particle-domain mean of w''
    return (dwq((x[:, None] + dx / 2 - yi[None, :]) / h) - dwq((x[:, None] - dx / 2 - yi[None, :]) / h)) / (h * dx)


def pt(x, yi):
    r = (x[:, None] - yi[None, :]) / h
    W = wq(r)
    return W, dwq(r) / h, W * (yi[None, :] - x[:, None]) * 4 / h ** 2, d2wq(r) / h ** 2


def std_scheme(kind):
    def sch(x, yi, dx):
        W, Bw, G, _ = pt(x, yi)
        B = Bw if kind == 'apic' else G
        def fint(u):
            J = np.exp(B @ u); p = press(J)
            return B.T @ (dx * J * p), p
        return dict(fint=fint, load=g * rho * dx * W.sum(0), W=W, S0=B)
    return sch


def solve(scheme, ppa, j, shift=True, it=10, ghost_ops=None, floorw='ghost', ext=None):
    Y, x, yi, dx, ps, Jex = lin.setup(ppa, j, shift)
    sc = scheme(x, yi, dx)
    act = sc['W'].sum(0) > 0
    idx = np.where(act)[0]
    n0 = len(yi)
    # ghost weights for the floor with the scheme's own force operator on a mirrored lattice
    yq = -(np.arange(40) + 0.5) * dx
    scg = scheme(yq, yi, dx)
    c = scg['S0'].sum(0)[act]; c = c / c.sum()
    wfl = wq((0 - yi[act]) / h)
    if floorw == 'own':
        c = wfl / wfl.sum()
    load = sc['load'][act]
    n = len(idx)
    E = np.eye(n)
    if ext is not None:   # extended B-splines: outer nodes (mass < a rho h) extrapolated, top side only
        import dyn as _d
        mi = rho * dx * sc['W'].sum(0)[act]
        E = _d.extension(np.where(yi[act] < H / 2, np.maximum(mi, rho * h), mi), x, yi[act], dx, ext, 2)
    nr = E.shape[1]

    def F(zr):
        z = np.concatenate([E @ zr[:nr], [zr[nr]]])
        u = np.zeros(n0); u[idx] = z[:nfull]
        f, p = sc['fint'](u)
        return np.concatenate([E.T @ (f[act] - load + z[nfull] * c), [wfl @ z[:nfull] / h]]), p
    nfull = n
    n = nr

    z = np.zeros(n + 1)
    for k in range(it):
        R, p = F(z)
        A = np.zeros((n + 1, n + 1))
        for q in range(n + 1):
            dz = np.zeros(n + 1); dz[q] = 1e-9 if q < n else 1e-3
            A[:, q] = (F(z + dz)[0] - R) / dz[q]
        step = np.linalg.lstsq(A, R, rcond=1e-12)[0]
        z = z - step
        if not np.all(np.isfinite(z)):
            break
    R, p = F(z)
    return dict(Y=Y, p=p, err=layer_err(Y, p), res=np.abs(R[:n]).max() / (rho * g * h), z=z)


def table(scheme, label, ppas=(2, 3), quiet=False, **kw):
    out = {}
    for ppa in ppas:
        tops, inner, bot, res = [], [], [], []
        for j in range(8):
            try:
                o = solve(scheme, ppa, j, **kw)
                e = o['err']; r = o['res']
            except Exception as ex:
                e = np.full(NL, np.nan); r = np.nan
            tops.append(e[-1] * 100); inner.append(np.abs(e[1:-1]).max() * 100)
            bot.append(abs(e[0]) * 100); res.append(r)
        out[ppa] = dict(top=tops, inner=max(inner), bottom=max(bot), res=max(res))
        if not quiet:
            print('%-16s ppa%d top%%: %s | max|L1..14| %.2f | max|L0| %.2f | resid %.0e' % (
                label, ppa, ' '.join('%6.2f' % t for t in tops), max(inner), max(bot), max(res)))
    return out


def m1bar(x, yi, dx):         # (1/V) int_{Omega_p} (y - y_p) w_i'(y) dy  (exact)
    dx = _c(dx)
    wa = wq((x[:, None] - dx / 2 - yi[None, :]) / h)
    wb = wq((x[:, None] + dx / 2 - yi[None, :]) / h)
    return 0.5 * (wa + wb) - wbar(x, yi, dx)


def gimp_linear(grad_source='strain'):
    """Particle-domain (uGIMP) integration with a LINEAR stress in each domain:
    f_i = sum_p V_p [p_p Sbar_ip + p'_p M1_ip], load = g sum_p m_p wbar_ip.
    strain: e_p = Sbar u (domain-mean strain) ; p' from the L2-projected strain slope
    g_p = 12/dx^2 (M1 u)_p (energy-consistent), or from a grid least-squares fit."""
    def sch(x, yi, dx):
        Wb, Sb, M1 = wbar(x, yi, dx), sbar(x, yi, dx), m1bar(x, yi, dx)
        W = wq((x[:, None] - yi[None, :]) / h)
        def fint(u):
            e = Sb @ u; J = np.exp(e); p = press(J)
            if grad_source == 'strain':
                gp = 12 / dx ** 2 * (M1 @ u)
                pg = -K * J ** (-gam) * gp
            elif grad_source == 'none':
                pg = 0 * p
            else:
                pg = grad_source(x, yi, dx, p, W)
            return Sb.T @ (dx * J * p) + M1.T @ (dx * J * pg), p
        return dict(fint=fint, load=g * rho * dx * Wb.sum(0), W=Wb, S0=Sb)
    return sch


def point_2nd(kind='apic', grad_source='strain'):
    """Point (APIC/MLS) force plus the second-order term of the particle-domain integral:
    f_i = sum_p V_p [p_p B_ip + dx^2/12 p'_p w_i''(y_p)], load = g m sum_p [w + dx^2/24 w'']."""
    def sch(x, yi, dx):
        W, Bw, G, D2 = pt(x, yi)
        B = Bw if kind == 'apic' else G
        def fint(u):
            e = B @ u; J = np.exp(e); p = press(J)
            if grad_source == 'strain':
                pg = -K * J ** (-gam) * (D2 @ u)
            else:
                pg = grad_source(x, yi, dx, p, W)
            return B.T @ (dx * J * p) + dx ** 2 / 12 * D2.T @ (dx * J * pg), p
        return dict(fint=fint, load=g * rho * dx * (W + dx ** 2 / 24 * D2).sum(0), W=W, S0=B)
    return sch


def grid_ls_grad(x, yi, dx, p, W, reg=1e-6):
    """Pressure gradient at particles from nodal weighted linear least-squares fits
    p ~ a_i + b_i (y - y_i) over each node's particles (weights w_ip), b_p = sum_i w_ip b_i / sum_i w_ip
    using only nodes whose fit is well posed (moment determinant above reg)."""
    dyv = x[:, None] - yi[None, :]
    M0 = W.sum(0); M1 = (W * dyv).sum(0); M2 = (W * dyv ** 2).sum(0)
    P0 = (W * p[:, None]).sum(0); P1 = (W * dyv * p[:, None]).sum(0)
    det = M0 * M2 - M1 ** 2
    ok = det > reg * (M0.max() * h) ** 2
    b = np.where(ok, (M0 * P1 - M1 * P0) / np.where(ok, det, 1), 0.0)
    Wk = W * ok[None, :]
    return (Wk @ b) / Wk.sum(1)


def combo(strain='apic', force='domlin', mass='bar', pgrad='strain'):
    """strain: 'apic' (w'), 'mls' (G), 'gimp' (Sbar) -- operator for e_p = B u (F update)
    force : 'point' (B^T V p), 'domconst' (Sbar^T V p), 'domlin' (Sbar^T V p + M1^T V p')
    mass  : 'point' (load = g sum m w_ip) or 'bar' (g sum m wbar_ip)
    pgrad : 'strain' (p' = dp/de * 12/dx^2 M1 u) or grid_ls_grad"""
    def sch(x, yi, dx):
        W, Bw, G, D2 = pt(x, yi)
        Wb, Sb, M1 = wbar(x, yi, dx), sbar(x, yi, dx), m1bar(x, yi, dx)
        B = {'apic': Bw, 'mls': G, 'gimp': Sb}[strain]
        def fint(u):
            e = B @ u; J = np.exp(e); p = press(J); V = dx * J
            if force == 'point':
                return B.T @ (V * p), p
            f = Sb.T @ (V * p)
            if force == 'domlin':
                if pgrad == 'strain':
                    pg = -K * J ** (-gam) * 12 / dx ** 2 * (M1 @ u)
                else:
                    pg = pgrad(x, yi, dx, p, W)
                f = f + M1.T @ (V * pg)
            return f, p
        Wl = Wb if mass == 'bar' else W
        Wact = Wb if force != 'point' else W
        return dict(fint=fint, load=g * rho * dx * Wl.sum(0), W=Wact + Wl, S0=(Sb if force != 'point' else B))
    return sch


def grid_ls_value(x, yi, vals, W, reg=1e-6):
    """Nodal weighted linear LS fits of particle values, evaluated back at the particles
    (partition-of-unity blend over well-posed nodes). Exact for linear fields, one-sided too."""
    dyv = x[:, None] - yi[None, :]
    M0 = W.sum(0); M1 = (W * dyv).sum(0); M2 = (W * dyv ** 2).sum(0)
    P0 = (W * vals[:, None]).sum(0); P1 = (W * dyv * vals[:, None]).sum(0)
    det = M0 * M2 - M1 ** 2
    ok = det > reg * (M0.max() * h) ** 2
    dd = np.where(ok, det, 1)
    b = np.where(ok, (M0 * P1 - M1 * P0) / dd, 0.0)
    a = np.where(ok, (M2 * P0 - M1 * P1) / dd, 0.0)
    Wk = W * ok[None, :]
    return (Wk * (a[None, :] + b[None, :] * dyv)).sum(1) / Wk.sum(1)
