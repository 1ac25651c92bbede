#!/usr/bin/env python3
"""Three discrete bending energies on the validation strip, in small-deflection theory.

Linearised about the flat strip (out-of-plane displacement z only), each energy is a
quadratic form 1/2 z^T K z. The script measures, for regular and irregular meshes of the
1 m x 0.1 m strip of scenes/validation/cantilever.json:

  * consistency: the energy of an imposed uniform curvature (bending along x, along y,
    twist) divided by the plate's, A k^T Q k with Q the Kirchhoff density;
  * the cantilever: the tip deflection of the strip clamped by its first two vertex columns
    under a uniform load, divided by the plate's q L^4 / (8 D) (L the free length).

The energies:

  hinge    sum over interior edges of k a_e theta_e^2, k = D / 6, a_e = 3 l_e^2 / (A + A~)
           (weft's hinge bending with bending_calibration = plate; docs/methods/shells.md);
  shape    per triangle, the shape operator S_T = sum_i theta_i l_i / (2 A) n_i n_i^T of its
           three hinge angles (Grinspun et al. 2006, "Computing discrete shape operators on
           general meshes", mid-edge normals at the bisector) in the plate density
           D / 2 ((1 - nu) tr S^2 + nu (tr S)^2) A, a missing (boundary) hinge minimised
           out: the free edge carries no moment;
  exact    the same with S_T the unique curvature that reproduces the triangle's linearised
           hinge angles under every uniform curvature (exact for uniform bending on any mesh).

The irregular meshes flip cell diagonals at random and jitter interior vertices by up to
0.3 of a cell, like weft's mesh.irregular but with NumPy's generator: the meshes are not
weft's. Run: python3 bench/bending_energies.py > bench/results/validation/bending_energies.csv
"""
import numpy as np

MESHES = [(31, 4), (61, 6), (88, 9), (98, 14)]


def strip(nx, ny, irregular, seed=7, length=1.0, width=0.1):
    rng = np.random.default_rng(seed)
    hx, hy = length / (nx - 1), width / (ny - 1)
    V = np.array([[-length / 2 + i * hx, -width / 2 + j * hy] for j in range(ny) for i in range(nx)])
    F = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a, b, c, d = j * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1, (j + 1) * nx + i
            F += [(a, b, d), (b, c, d)] if irregular and rng.integers(2) else [(a, b, c), (a, c, d)]
    if irregular:
        jitter = rng.uniform(-0.3, 0.3, (len(V), 2)) * [hx, hy]
        on_boundary = np.array([i in (0, nx - 1) or j in (0, ny - 1) for j in range(ny) for i in range(nx)])
        jitter[on_boundary] = 0
        V = V + jitter
    return V, np.array(F)


def edge_faces(F):
    E = {}
    for f, t in enumerate(F):
        for i in range(3):
            a, b = t[(i + 1) % 3], t[(i + 2) % 3]
            E.setdefault((min(a, b), max(a, b)), []).append((f, i))
    return E


def area(V, t):
    (x0, y0), (x1, y1), (x2, y2) = V[t[0]], V[t[1]], V[t[2]]
    return 0.5 * ((x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0))


def dihedral(P, F, faces):
    (f1, i1), (f2, _) = faces
    n = [np.cross(P[F[f][1]] - P[F[f][0]], P[F[f][2]] - P[F[f][0]]) for f in (f1, f2)]
    n = [v / np.linalg.norm(v) for v in n]
    t = F[f1]
    e = P[t[(i1 + 2) % 3]] - P[t[(i1 + 1) % 3]]
    return np.arctan2(np.dot(np.cross(n[0], n[1]), e / np.linalg.norm(e)), np.dot(n[0], n[1]))


def hinge_gradients(V, F, E, eps=1e-6):
    """d theta_e / d z_v at the flat strip, by central differences of the exact angle."""
    P0 = np.c_[V, np.zeros(len(V))]
    G = {}
    for e, faces in E.items():
        if len(faces) < 2:
            continue
        g = {}
        for v in sorted(set(F[faces[0][0]]) | set(F[faces[1][0]])):
            P = P0.copy()
            P[v, 2] = eps
            plus = dihedral(P, F, faces)
            P[v, 2] = -eps
            g[v] = (plus - dihedral(P, F, faces)) / (2 * eps)
        G[e] = g
    return G


def plate_density(nu):
    """Q with k^T Q k = 1/2 ((1 - nu) tr S^2 + nu (tr S)^2), k = (S_xx, S_yy, S_xy), D = 1."""
    return 0.5 * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, 2 * (1 - nu)]])


def scatter(K, G, hinges, Kt):
    vs = sorted(set(v for e in hinges for v in G[e]))
    Gm = np.zeros((len(hinges), len(vs)))
    for r, e in enumerate(hinges):
        for v, g in G[e].items():
            Gm[r, vs.index(v)] = g
    K[np.ix_(vs, vs)] += 2 * Gm.T @ Kt @ Gm


def K_hinge(V, F, E, G, nu):
    K = np.zeros((len(V), len(V)))
    for e, g in G.items():
        (f1, _), (f2, _) = E[e]
        l2 = np.sum((V[e[0]] - V[e[1]]) ** 2)
        scatter(K, G, [e], np.array([[(1 / 6) * 3 * l2 / (area(V, F[f1]) + area(V, F[f2]))]]))
    return K


def K_shape(V, F, E, G, nu, exact):
    K = np.zeros((len(V), len(V)))
    Q = plate_density(nu)
    for f, t in enumerate(F):
        A = area(V, t)
        rows, hinges = [], []
        for i in range(3):
            a, b = t[(i + 1) % 3], t[(i + 2) % 3]
            d = V[b] - V[a]
            l = np.linalg.norm(d)
            n = np.array([d[1], -d[0]]) / l
            e = (min(a, b), max(a, b))
            if exact and e in G:  # theta_e under z = k^T (x^2, y^2, 2xy) / 2
                q = np.array([[V[v, 0] ** 2, V[v, 1] ** 2, 2 * V[v, 0] * V[v, 1]] for v in G[e]]) / 2
                rows.append(np.array(list(G[e].values())) @ q)
            else:  # S_T = sum theta_i B_i: the hinge's row of the inverse map
                rows.append(np.array([n[0] ** 2, n[1] ** 2, n[0] * n[1]]) * l / (2 * A))
            hinges.append(e if e in G else None)
        M = np.array(rows)
        if not exact:  # k = M^T theta; the energy A theta^T M Q M^T theta
            Kt = A * M @ Q @ M.T
            inner = [i for i in range(3) if hinges[i]]
            outer = [i for i in range(3) if not hinges[i]]
            if not inner:
                continue
            Ki = Kt[np.ix_(inner, inner)]
            if outer:
                Ki = Ki - Kt[np.ix_(inner, outer)] @ np.linalg.solve(Kt[np.ix_(outer, outer)], Kt[np.ix_(outer, inner)])
        else:  # theta = M k: the least plate energy among the curvatures that give theta
            inner = [i for i in range(3) if hinges[i]]
            if not inner:
                continue
            Mi = M[inner]
            Ki = A * np.linalg.inv(Mi @ np.linalg.inv(Q) @ Mi.T)
        scatter(K, G, [hinges[i] for i in inner], Ki)
    return K


def consistency(V, F, K, nu):
    A = sum(area(V, t) for t in F)
    out = []
    for k in ([1, 0, 0], [0, 1, 0], [0, 0, 1]):
        k = np.array(k, float)
        z = 0.5 * (k[0] * V[:, 0] ** 2 + k[1] * V[:, 1] ** 2 + 2 * k[2] * V[:, 0] * V[:, 1])
        out.append(0.5 * z @ K @ z / (A * k @ plate_density(nu) @ k))
    return out


def cantilever(V, F, K, nx, length=1.0):
    hx = length / (nx - 1)
    free = V[:, 0] > -length / 2 + 1.5 * hx
    load = np.zeros(len(V))
    for t in F:
        load[t] += area(V, t) / 3
    z = np.zeros(len(V))
    z[free] = np.linalg.solve(K[np.ix_(free, free)], load[free])
    tip = V[:, 0] > length / 2 - 1e-9
    return z[tip].mean() / ((length - hx) ** 4 / 8)


def main():
    print("mesh,energy,nu,bend_x,bend_y,twist,cantilever,beam_reference")
    for irregular in (False, True):
        for nx, ny in MESHES:
            V, F = strip(nx, ny, irregular)
            E = edge_faces(F)
            G = hinge_gradients(V, F, E)
            name = f"{'irregular' if irregular else 'regular'}-{nx}x{ny}"
            for nu in (0.3, 0.0):
                for energy, K in (("hinge", K_hinge(V, F, E, G, nu)),
                                  ("shape", K_shape(V, F, E, G, nu, exact=False)),
                                  ("exact", K_shape(V, F, E, G, nu, exact=True))):
                    c = consistency(V, F, K, nu)
                    print(f"{name},{energy},{nu},{c[0]:.4f},{c[1]:.4f},{c[2]:.4f},"
                          f"{cantilever(V, F, K, nx):.4f},{1 / (1 - nu * nu):.4f}", flush=True)


if __name__ == "__main__":
    main()
