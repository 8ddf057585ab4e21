"""Dynamic 1D replica (as dyn.py: unloaded start, grid damping 150/s, dt = 0.5 h/c, 0.5 s,
floor contact at the particles with ghost weights) with selectable force / F-update operators:

  fgrad : operator for the J update (velocity divergence at the particle):
          'apic' point w'(x_p) ; 'mls' C_p = 4/h^2 sum w v (x_i-x_p) ; 'gimp' domain mean of w'
  force : 'point'    f_i = sum V p B_i   with B the fgrad operator (engine as is)
          'domconst' f_i = sum V p Sbar_i (uGIMP, constant stress over the particle domain)
          'domlin'   f_i = sum V (p Sbar_i + p' M1_i): linear stress over the particle domain,
                     integrated exactly against w_i'; p' = dp/dJ J gam_p from a stored
                     per-particle gradient of log J, gam_p += dt 12/l^2 sum_i v_i M1_ip
                     ('state'), or p' from nodal least-squares fits ('gridls').
  mass  : 'point' (m_i = sum m w_ip, gravity g m_i) or 'bar' (P2G mass/momentum and G2P with the
          domain-mean weights wbar; gravity g m_i then integrates rho g w_i exactly).
  dom   : particle domain length: 'u' (dx, undeformed) or 'cp' (J dx, updated).
"""
import numpy as np
from model import rho, K, gam, g, H, h, NL, wq, dwq, press, layer_err
import lin
from schemes import wbar, sbar, m1bar, grid_ls_grad, grid_ls_value


def run(ppa, j, fgrad='apic', force='point', mass='point', pgrad='state', dom='u', T=0.5,
        rate=150.0, cfl=0.5, init='unloaded', floorw='ghost'):
    dx = h / ppa
    Y = (np.arange(NL * ppa) + 0.5) * dx
    x = Y.copy()
    yi = -j * h / 8 + np.arange(-3, NL + 4) * h
    n = len(yi)
    m = rho * dx
    v = np.zeros_like(x); C = np.zeros_like(x); J = np.ones_like(x); gm = np.zeros_like(x)
    if init == 'exact':
        _, x, _, _, _, J = lin.setup(ppa, j); x = x.copy(); J = J.copy()
    c = np.sqrt(K / rho)
    dt = cfl * h / c
    nsteps = int(round(T / dt))
    damp = np.exp(-rate * dt)
    wfl = wq((0.0 - yi) / h)
    # ghost weights: force of a mirrored body under uniform pressure, with the force operator used
    yq = -(np.arange(40) + 0.5) * dx
    if force == 'point':
        rq = (yq[:, None] - yi[None, :]) / h
        Sg = dwq(rq) / h if not fgrad.startswith('mls') else wq(rq) * (yi[None, :] - yq[:, None]) * 4 / h ** 2
    else:
        Sg = sbar(yq, yi, dx)
    cgh = Sg.sum(0); cgh /= cgh.sum()
    if floorw == 'own':
        cgh = wfl / wfl.sum()
    for step in range(nsteps):
        l = dx * J if dom == 'cp' else np.full_like(x, dx)
        r = (x[:, None] - yi[None, :]) / h
        W = wq(r); Bw = dwq(r) / h
        Xd = (yi[None, :] - x[:, None])
        Wb = Sb = M1 = None
        if force != 'point' or mass == 'bar' or fgrad == 'gimp':
            Wb = wbar(x, yi, l)
            clip = force.endswith('_clip')
            Sb = sbar(x, yi, l)
            M1 = m1bar(x, yi, l)
            if clip:   # keep the particle's point stencil (27 nodes in 3D): drop the domain's extra nodes
                Sb = Sb * (W > 0); M1 = M1 * (W > 0)
        Wt = Wb if mass == 'bar' else W
        V = dx * J
        p = press(J)
        mi = m * Wt.sum(0)
        mom = Wt.T @ (m * v) + (Wt * Xd).T @ (m * C)
        if force == 'point':
            b0 = fgrad.partition('_')[0]
            S = Bw if b0 == 'apic' else (W * Xd * 4 / h ** 2 if b0 == 'mls' else Sb)
            f = S.T @ (V * p)
        else:
            f = Sb.T @ (V * p)
            if force.startswith('domlin'):
                if pgrad == 'state':
                    pg = -K * J ** (-gam) * gm
                else:
                    pg = grid_ls_grad(x, yi, dx, p, W)
                f = f + M1.T @ (V * pg)
        act = mi > 0
        vi = np.zeros(n)
        vi[act] = (mom[act] + dt * f[act]) / mi[act] - g * dt
        vi *= damp
        vc = wfl @ vi
        if vc < 0:
            a = np.sum(wfl[act] * cgh[act] / mi[act])
            vi[act] += (-vc / a) * cgh[act] / mi[act]
        vp = Wt @ vi
        Cp = (Wt * Xd) @ vi * 4.0 / h ** 2
        base, _, smooth = fgrad.partition('_')
        if base == 'apic':
            gv = Bw @ vi
        elif base == 'mls':
            gv = (W * Xd) @ vi * 4.0 / h ** 2
        else:
            gv = Sb @ vi
        if smooth == 'ls':      # volumetric rate smoothed by nodal linear least-squares reconstruction
            gv = grid_ls_value(x, yi, gv, W)
        elif smooth == 'avg':   # node-averaged volumetric rate (J-bar / F-bar style)
            Wv = W * V[:, None]
            dn = (Wv * gv[:, None]).sum(0) / np.maximum(Wv.sum(0), 1e-300)
            gv = W @ dn
        if force.startswith('domlin') and pgrad == 'state':
            gm = gm + dt * 12 / l ** 2 * (M1 @ vi)
        J = J * (1 + dt * gv)
        x = x + dt * vp
        v, C = vp, Cp
    pr = press(J)
    return dict(Y=Y, p=pr, err=layer_err(Y, pr), vmax=np.abs(v).max(), J=J)


def table(label, ppas=(2, 3), **kw):
    out = {}
    for ppa in ppas:
        tops, inner, bot, vm = [], [], [], []
        for j in range(8):
            o = run(ppa, j, **kw)
            e = o['err']
            tops.append(e[-1] * 100); inner.append(np.abs(e[1:-1]).max() * 100); bot.append(abs(e[0]) * 100)
            vm.append(o['vmax'])
        out[ppa] = dict(top=tops, inner=max(inner), bottom=max(bot))
        print('%-28s ppa%d top%%: %s | max|L1..14| %.2f | max|L0| %.2f | vmax %.0e' % (
            label, ppa, ' '.join('%6.2f' % t for t in tops), max(inner), max(bot), max(vm)), flush=True)
    return out


if __name__ == '__main__':
    import sys
    kw = eval(sys.argv[1]) if len(sys.argv) > 1 else {}
    ppas = eval(sys.argv[2]) if len(sys.argv) > 2 else (2, 3)
    table(str(kw), ppas, **kw)
