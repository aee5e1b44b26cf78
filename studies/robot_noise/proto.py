#!/usr/bin/env python3
"""A numpy prototype of the one-stage adjustment's chain part (camera fu fv u0 v0 k1 k2,
X, Z, optional board scale, per-view flange corrections D_i with a prior), to try noise
models on real data without rebuilding the Rust crate. Projection by cv2.projectPoints
(radial2 = OpenCV's k1, k2; the conic centre offset of circles is ignored: it is far below
the effects studied here). The detections, the labelling and the starting values come from
`stripecal.calibrate` (the rigid model).

Noise models of the per-view correction's prior covariance S_i (6 x 6, rotation rad then
translation mm, flange frame), each a sum of variance components estimated with the
image's (Foerstner's iteration, `theta_k <- theta_k (theta_k v' W V_k W v) / r_k`):

    rigid   no correction
    robot   S_i = diag(s_r^2 I, s_t^2 I)                      (what the crate does today)
    image   S_i = k^2 Q_i,   Q_i the view's own image covariance of D_i (white image noise)
    both    S_i = diag(s_r^2 I, s_t^2 I) + k^2 Q_i

    python studies/robot_noise/proto.py SET [--scale] [--model M] [--split] [--loo] [--jack]
"""
import argparse
import os
import sys

import cv2
import numpy as np
import stripecal

np.set_printoptions(linewidth=200, precision=4, suppress=True)


def rotvec(R):
    return cv2.Rodrigues(np.asarray(R, float))[0].ravel()


def rotm(w):
    return cv2.Rodrigues(np.asarray(w, float).reshape(3, 1))[0]


def T(R, t):
    m = np.eye(4)
    m[:3, :3] = R
    m[:3, 3] = t
    return m


class Data:
    """Detections, flange poses and start values of a set (all views)."""

    def __init__(self, folder, scale_free):
        ds = stripecal.load_dataset(folder)
        cal = stripecal.calibrate(ds, leave_one_out=False, estimate_board_scale=scale_free, accept_poor=True)
        self.cam0 = cal.camera
        self.X0, self.Z0 = np.asarray(cal.hand_cam), np.asarray(cal.base_board)
        self.s0 = cal.board_scale["scale"] if scale_free else 1.0
        self.size = (cal.camera.width, cal.camera.height)
        b = ds.rig.board
        C, I = np.asarray(b.centers()), np.asarray(b.indices())
        cmap = {(int(a), int(c)): C[k] for k, (a, c) in enumerate(I)}
        r = np.asarray(cal.circle_residuals)
        self.views = []
        for v in np.unique(r[:, 0]).astype(int):
            m = r[r[:, 0] == v]
            obj = np.array([[*cmap[(int(a), int(c))][:2], 0.0] for a, c in m[:, 1:3]])
            self.views.append((v, np.asarray(ds.views[v]["flange_pose"]), obj, m[:, 3:5].copy()))
        self.scale_free = scale_free


class Model:
    """State, residuals, Jacobian, variance components."""

    def __init__(self, data, views, model, comps=None, reestimate=True):
        self.d = data
        self.vs = [data.views[i] for i in views]
        self.model = model
        c = data.cam0
        self.cam = np.array([c.fu, c.fv, c.u0, c.v0, c.distortion[0], c.distortion[1]]) if CAM is None else CAM.copy()
        self.X, self.Z, self.s = data.X0.copy(), data.Z0.copy(), data.s0
        self.D = [np.eye(4) for _ in self.vs]
        self.ng = 6 + 12 + (1 if data.scale_free else 0)
        self.sw = 0.2  # image sigma px
        # components: rotation rad^2, translation mm^2, image-pose factor k^2
        self.th = dict(r=(0.05 * np.pi / 180) ** 2, t=0.5 ** 2, k=1.0) if comps is None else dict(comps)
        self.reestimate = reestimate
        self.use = {"rigid": (), "robot": ("r", "t"), "image": ("k",), "both": ("r", "t", "k")}[model]
        self.Q = [np.eye(6) for _ in self.vs]

    # ---- geometry
    def project(self, cam, X, Z, s, A, D, obj):
        Tcb = np.linalg.inv(A @ D @ X) @ Z
        K = np.array([[cam[0], 0, cam[2]], [0, cam[1], cam[3]], [0, 0, 1.0]])
        p, _ = cv2.projectPoints(obj * s, rotvec(Tcb[:3, :3]), Tcb[:3, 3], K, np.r_[cam[4:6], 0, 0])
        return p.reshape(-1, 2)

    def image_res(self, st):
        cam, X, Z, s, D = st
        return [(self.project(cam, X, Z, s, A, D[i], obj) - uv).ravel() for i, (_, A, obj, uv) in enumerate(self.vs)]

    def state(self):
        return (self.cam, self.X, self.Z, self.s, self.D)

    def retract(self, st, dg, dd):
        cam, X, Z, s, D = st
        cam = cam + dg[:6]
        X = T(X[:3, :3] @ rotm(dg[6:9]), X[:3, 3] + dg[9:12])
        Z = T(Z[:3, :3] @ rotm(dg[12:15]), Z[:3, 3] + dg[15:18])
        if self.d.scale_free:
            s = s + dg[18]
        D = [T(Di[:3, :3] @ rotm(dd[i][:3]), Di[:3, 3] + dd[i][3:]) for i, Di in enumerate(D)]
        return (cam, X, Z, s, D)

    def prior_raw(self, D):
        return [np.r_[rotvec(Di[:3, :3]), Di[:3, 3]] for Di in D]

    def jacobians(self):
        st = self.state()
        r0 = self.image_res(st)
        nv = len(self.vs)
        Jg = [np.zeros((len(r), self.ng)) for r in r0]
        Jd = [np.zeros((len(r), 6)) for r in r0]
        for j in range(self.ng):
            h = 1e-6 if j >= 4 else 1e-4
            dg = np.zeros(self.ng)
            dg[j] = h
            rp = self.image_res(self.retract(st, dg, [np.zeros(6)] * nv))
            dg[j] = -h
            rm = self.image_res(self.retract(st, dg, [np.zeros(6)] * nv))
            for i in range(nv):
                Jg[i][:, j] = (rp[i] - rm[i]) / (2 * h)
        for j in range(6):
            dd = [np.zeros(6) for _ in range(nv)]
            for x in dd:
                x[j] = 1e-6
            rp = self.image_res(self.retract(st, np.zeros(self.ng), dd))
            for x in dd:
                x[j] = -1e-6
            rm = self.image_res(self.retract(st, np.zeros(self.ng), dd))
            for i in range(nv):
                Jd[i][:, j] = (rp[i] - rm[i]) / 2e-6
        return r0, Jg, Jd

    def S(self, i):
        th = self.th
        S = np.zeros((6, 6))
        if "r" in self.use:
            S[:3, :3] += th["r"] * np.eye(3)
            S[3:, 3:] += th["t"] * np.eye(3)
        if "k" in self.use:
            S += th["k"] * self.Q[i]
        return S

    def normal(self, r0, Jg, Jd):
        """Normal equations over (global, per-view D) with weights; returns N, g, layout."""
        nv = len(self.vs)
        n = self.ng + (6 * nv if self.use else 0)
        N = np.zeros((n, n))
        g = np.zeros(n)
        w = 1.0 / self.sw ** 2
        pr = self.prior_raw(self.D)
        for i in range(nv):
            J = Jg[i]
            N[: self.ng, : self.ng] += w * J.T @ J
            g[: self.ng] += w * J.T @ r0[i]
            if self.use:
                o = self.ng + 6 * i
                N[: self.ng, o:o + 6] += w * J.T @ Jd[i]
                N[o:o + 6, : self.ng] += w * Jd[i].T @ J
                N[o:o + 6, o:o + 6] += w * Jd[i].T @ Jd[i]
                g[o:o + 6] += w * Jd[i].T @ r0[i]
                P = np.linalg.inv(self.S(i))
                N[o:o + 6, o:o + 6] += P
                g[o:o + 6] += P @ pr[i]
        if CAM is not None:
            N[:6, :6] += 1e14 * np.eye(6)
        return N, g

    def cost(self, st):
        c = sum((r ** 2).sum() for r in self.image_res(st)) / self.sw ** 2
        if self.use:
            for i, p in enumerate(self.prior_raw(st[4])):
                c += p @ np.linalg.solve(self.S(i), p)
        return c

    def solve(self, iters=30, verbose=False):
        nv = len(self.vs)
        lam = 1e-3
        for it in range(iters):
            r0, Jg, Jd = self.jacobians()
            # the view's own image covariance of its correction (white noise)
            self.Q = [self.sw ** 2 * np.linalg.inv(J.T @ J) for J in Jd]
            N, g = self.normal(r0, Jg, Jd)
            c0 = self.cost(self.state())
            while True:
                dx = -np.linalg.solve(N + lam * np.diag(np.diag(N)), g)
                dd = [dx[self.ng + 6 * i: self.ng + 6 * i + 6] if self.use else np.zeros(6) for i in range(nv)]
                st = self.retract(self.state(), dx[: self.ng], dd)
                c1 = self.cost(st)
                if c1 <= c0 or lam > 1e6:
                    break
                lam *= 10
            if c1 <= c0:
                self.cam, self.X, self.Z, self.s, self.D = st
                lam = max(lam / 10, 1e-9)
            moved = self.update_components() if self.reestimate else False
            if verbose:
                print(it, c0, c1, self.sw, self.th)
            if not moved and abs(c0 - c1) < 1e-6 * c0:
                break
        r0, Jg, Jd = self.jacobians()
        self.Q = [self.sw ** 2 * np.linalg.inv(J.T @ J) for J in Jd]
        N, g = self.normal(r0, Jg, Jd)
        self.C = np.linalg.inv(N)
        self.r0, self.Jg, self.Jd = r0, Jg, Jd
        return self

    def update_components(self):
        """Foerstner: theta_k <- theta_k * (theta_k v' W V_k W v) / r_k for every component."""
        r0, Jg, Jd = self.jacobians()
        Q = [self.sw ** 2 * np.linalg.inv(J.T @ J) for J in Jd]
        self.Q = Q
        N, g = self.normal(r0, Jg, Jd)
        C = np.linalg.inv(N)
        nv = len(self.vs)
        w = 1.0 / self.sw ** 2
        # image group: redundancy m - sum of leverages
        m_img = sum(len(r) for r in r0)
        lev = 0.0
        for i in range(nv):
            cols = list(range(self.ng)) + (list(range(self.ng + 6 * i, self.ng + 6 * i + 6)) if self.use else [])
            J = np.hstack([Jg[i], Jd[i]]) if self.use else Jg[i]
            Ci = C[np.ix_(cols, cols)]
            lev += w * np.einsum("ij,jk,ik->", J, Ci, J)
        ss = sum((r ** 2).sum() for r in r0)
        new_sw = np.sqrt(ss / (m_img - lev))
        moved = abs(new_sw / self.sw - 1) > 1e-3
        if self.use:
            pr = self.prior_raw(self.D)
            num = {k: 0.0 for k in self.use}
            red = {k: 0.0 for k in self.use}
            for i in range(nv):
                o = self.ng + 6 * i
                S = self.S(i)
                P = np.linalg.inv(S)
                Rii = P - P @ C[o:o + 6, o:o + 6] @ P  # prior rows' Jacobian ~ identity
                Pv = P @ pr[i]
                for k in self.use:
                    V = {"r": np.diag([1, 1, 1, 0, 0, 0.0]), "t": np.diag([0, 0, 0, 1, 1, 1.0]), "k": Q[i]}[k]
                    num[k] += self.th[k] ** 2 * Pv @ V @ Pv
                    red[k] += self.th[k] * np.trace(V @ Rii)
            for k in self.use:
                if self.reestimate == "image":
                    continue
                if red[k] > 1e-9:
                    new = num[k] / red[k]
                    floor = {"r": (1e-4 * np.pi / 180) ** 2, "t": 1e-6, "k": 1e-6}[k]
                    new = max(new, floor)
                    moved |= abs(new / self.th[k] - 1) > 1e-3
                    self.th[k] = new
        self.sw = new_sw
        return moved

    def sigmas(self):
        c = np.sqrt(np.diag(self.C))
        return dict(fu=(self.cam[0], c[0]), fv=(self.cam[1], c[1]), u0=(self.cam[2], c[2]), v0=(self.cam[3], c[3]),
                    **{"X t" + a: (self.X[k, 3], c[9 + k]) for k, a in enumerate("xyz")})

    def reml(self):
        """-2 log of the restricted likelihood at the solution (linearised; constants
        dropped): m log sw^2 + sum log det S_i + log det N + weighted SS (Harville)."""
        m = sum(len(r) for r in self.r0)
        c = m * np.log(self.sw ** 2) + sum((r ** 2).sum() for r in self.r0) / self.sw ** 2
        if self.use:
            for i, p in enumerate(self.prior_raw(self.D)):
                S = self.S(i)
                c += np.linalg.slogdet(S)[1] + p @ np.linalg.solve(S, p)
        c -= np.linalg.slogdet(self.C)[1]
        return c

    def cluster_robust(self):
        """Sandwich by views (CR1-like: n/(n-1)), over the global parameters: bread C,
        meat sum of each view's score (its image rows and prior rows)."""
        nv = len(self.vs)
        w = 1.0 / self.sw ** 2
        n = self.C.shape[0]
        M = np.zeros((n, n))
        pr = self.prior_raw(self.D)
        for i in range(nv):
            s = np.zeros(n)
            s[: self.ng] = w * self.Jg[i].T @ self.r0[i]
            if self.use:
                o = self.ng + 6 * i
                s[o:o + 6] = w * self.Jd[i].T @ self.r0[i] + np.linalg.solve(self.S(i), pr[i])
            M += np.outer(s, s)
        return self.C @ M @ self.C * nv / (nv - 1)

    def jackknife(self):
        """One-step delete-one-view jackknife over the global parameters (module docs of
        the crate's covariance: (N - N_v)^-1 g_v per view, reduced by the view's own
        correction)."""
        nv = len(self.vs)
        w = 1.0 / self.sw ** 2
        ng = self.ng
        pr = self.prior_raw(self.D)
        Ms, gs = [], []
        for i in range(nv):
            Ngg = w * self.Jg[i].T @ self.Jg[i]
            gg = w * self.Jg[i].T @ self.r0[i]
            if self.use:
                P = np.linalg.inv(self.S(i))
                Ngd = w * self.Jg[i].T @ self.Jd[i]
                Ndd = w * self.Jd[i].T @ self.Jd[i] + P
                gd = w * self.Jd[i].T @ self.r0[i] + P @ pr[i]
                K = Ngd @ np.linalg.inv(Ndd)
                Ngg = Ngg - K @ Ngd.T
                gg = gg - K @ gd
            Ms.append(Ngg)
            gs.append(gg)
        N = sum(Ms)
        if CAM is not None:
            N[:6, :6] += 1e14 * np.eye(6)
        d = np.array([np.linalg.solve(N - Ms[i], gs[i]) for i in range(nv)])
        d -= d.mean(0)
        return (nv - 1) / nv * d.T @ d

    def combined(self):
        """The model covariance widened to the jackknife's where that is larger: in the
        model's whitened frame, eigenvalues max(1, lambda) (C >= both)."""
        ng = self.ng
        C = self.C[:ng, :ng]
        V = self.jackknife() if JACK else self.cluster_robust()[:ng, :ng]
        if CAM is not None:
            return C
        L = np.linalg.cholesky(C)
        Li = np.linalg.inv(L)
        W = Li @ V @ Li.T
        lam, U = np.linalg.eigh(0.5 * (W + W.T))
        return L @ U @ np.diag(np.maximum(lam, 1.0)) @ U.T @ L.T

    def predict_rms(self, v):
        _, A, obj, uv = v
        p = self.project(self.cam, self.X, self.Z, self.s, A, np.eye(4), obj)
        return np.sqrt(((p - uv) ** 2).sum(1).mean())


FIXED = None
CAM = None
JACK = "--jack" in sys.argv
WHITE = "--white" in sys.argv


def fit(data, idx, model, **kw):
    if FIXED is not None:
        kw = dict(kw, comps=FIXED, reestimate="image")
    return Model(data, idx, model, **kw).solve()


def loo(data, idx, model, hold=False):
    full = fit(data, idx, model)
    out = []
    for k in idx:
        rest = [i for i in idx if i != k]
        m = Model(data, rest, model, comps=full.th if hold or FIXED else None,
                  reestimate=("image" if FIXED else not hold))
        m.sw = full.sw
        m.cam, m.X, m.Z, m.s = full.cam.copy(), full.X.copy(), full.Z.copy(), full.s
        m.solve()
        out.append((k, m.predict_rms(data.views[k]), m))
    return full, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("set")
    ap.add_argument("--scale", action="store_true")
    ap.add_argument("--model", default="robot")
    ap.add_argument("--split", action="store_true")
    ap.add_argument("--loo", action="store_true")
    ap.add_argument("--hold", action="store_true", help="LOO refits hold the full fit's components")
    ap.add_argument("--comps", help="fixed components r_deg,t_mm,k (no re-estimation of the robot ones)")
    ap.add_argument("--white", action="store_true", help="the floor as the whitened max")
    ap.add_argument("--jack", action="store_true", help="the split's floor from the one-step jackknife")
    ap.add_argument("--camera-only", action="store_true", help="hold the camera at the image-only model's")
    a = ap.parse_args()
    global FIXED, CAM
    if a.camera_only:
        CAM = Model(Data(a.set, a.scale), list(range(len(Data(a.set, a.scale).views))), "image").solve().cam
        print("camera held at", CAM)
    if a.comps:
        r, t, k = map(float, a.comps.split(","))
        FIXED = dict(r=np.radians(r) ** 2, t=t * t, k=k * k)
    data = Data(a.set, a.scale)
    n = len(data.views)
    idx = list(range(n))
    full = fit(data, idx, a.model)
    th = full.th
    print("%s %s: sw %.4f px  s_r %.4f deg  s_t %.3f mm  k %.3f  scale %.4f" % (
        os.path.basename(a.set.rstrip("/")), a.model, full.sw, np.degrees(np.sqrt(th["r"])), np.sqrt(th["t"]), np.sqrt(th["k"]), full.s))
    print("  -2 log L_R %.2f" % full.reml())
    cr = np.sqrt(np.diag(full.jackknife() if JACK else full.cluster_robust()))
    for k, (val, sg) in full.sigmas().items():
        j = {"fu": 0, "fv": 1, "u0": 2, "v0": 3, "X tx": 9, "X ty": 10, "X tz": 11}[k]
        print("  %-5s %10.3f +- %.3f  (cluster-robust %.3f)" % (k, val, sg, cr[j]))
    if a.loo:
        _, out = loo(data, idx, a.model, hold=a.hold)
        px = [o[1] for o in out]
        print("  LOO median %.3f px  (%s)" % (np.median(px), " ".join("%.2f" % x for x in px)))
    if a.split:
        h = [fit(data, idx[p::2], a.model) for p in (0, 1)]
        zs, zc = [], []
        crs = [np.sqrt(np.diag(m.combined() if WHITE else (m.jackknife() if JACK else m.cluster_robust()))) for m in h]
        for k in ("fu", "u0", "v0", "X tx", "X ty", "X tz"):
            j = {"fu": 0, "fv": 1, "u0": 2, "v0": 3, "X tx": 9, "X ty": 10, "X tz": 11}[k]
            (x, sx), (y, sy) = h[0].sigmas()[k], h[1].sigmas()[k]
            z = (x - y) / np.hypot(sx, sy)
            zr = (x - y) / np.hypot(max(sx, crs[0][j]), max(sy, crs[1][j]))
            zs.append(z)
            zc.append(zr)
            print("  split %-5s %9.3f +- %.3f | %9.3f +- %.3f  z %+.2f  (with cluster-robust floor %+.2f)" % (k, x, sx, y, sy, z, zr))
        print("  split RMS z %.2f (cluster floor %.2f); components halves: %s" % (
            np.sqrt(np.mean(np.square(zs))), np.sqrt(np.mean(np.square(zc))),
            ["s_r %.3f deg s_t %.2f mm k %.2f" % (np.degrees(np.sqrt(m.th["r"])), np.sqrt(m.th["t"]), np.sqrt(m.th["k"])) for m in h]))


if __name__ == "__main__":
    main()
