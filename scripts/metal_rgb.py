#!/usr/bin/env python3
"""Reduces measured spectral complex indices of refraction (eta + i k) of metals to the RGB
triples of tracer/materials/metals.h. Run it to regenerate that table (it prints the C++ rows).

Data (wavelength in nm, eta, k):
- Ag, Al, Au, Cu: pbrt-v4's named spectra "metal-X-eta" / "metal-X-k" (src/pbrt/util/spectrum.cpp,
  arrays Ag_eta ... Cu_k), tabulated every 0.05 eV as in Palik's Handbook of Optical Constants of
  Solids (Academic Press, 1985).
- Cr, Ni, Ti: P. B. Johnson and R. W. Christy, "Optical constants of transition metals: Ti, V, Cr,
  Mn, Fe, Co, Ni, and Pd", Phys. Rev. B 9, 5056 (1974), as refractiveindex.info tabulates them
  (database/data-nk/main/{Cr,Ni,Ti}/Johnson.yml, CC0).

Reduction. An RGB renderer evaluates the exact Fresnel equations once per channel, so each
channel needs one (eta, k) whose reflectance looks like the spectrum's. Averaging eta and k over
a channel's colour matching function does not give that (Fresnel is not linear in them: the
average turns gold's red 0.89 where the spectrum's colour is 1.0, because sRGB's red function has
a lobe in the blue, where gold's eta is 1.5). So, per channel, (eta, k) are fitted by least squares
(Nelder-Mead) to the target curve R_c(theta) = channel c of the linear-sRGB colour of the spectral
unpolarised reflectance R(lambda, theta), over 32 angles weighted by cos sin (projected solid
angle). The colour is the CIE 1931 2-degree observer (the analytic fit of Wyman, Sloan & Shirley,
JCGT 2(2) 2013) under an equal-energy illuminant adapted to D65 (reflectance 1 is white),
380-780 nm in 1 nm steps, then the XYZ -> sRGB matrix of IEC 61966-2-1. Where that colour is out
of gamut (gold's red: 1.05 at normal incidence) the target is capped at the spectrum's own largest
reflectance at that angle. The fit starts from the CIE-weighted averages of eta and k; it prints
the residual (rms over angles) and F0 against the target's F0.
"""
import math

PBRT_L = [298.757050, 302.400421, 306.133759, 309.960449, 313.884003, 317.908142, 322.036835,
          326.274139, 330.624481, 335.092377, 339.682678, 344.400482, 349.251221, 354.240509,
          359.374420, 364.659332, 370.102020, 375.709625, 381.489777, 387.450562, 393.600555,
          399.948975, 406.505493, 413.280579, 420.285339, 427.531647, 435.032196, 442.800629,
          450.851562, 459.200653, 467.864838, 476.862213, 486.212463, 495.936707, 506.057861,
          516.600769, 527.592224, 539.061646, 551.040771, 563.564453, 576.670593, 590.400818,
          604.800842, 619.920898, 635.816284, 652.548279, 670.184753, 688.800964, 708.481018,
          729.318665, 751.419250, 774.901123, 799.897949, 826.561157, 855.063293, 885.601257]

PBRT = {
    "Ag": ([1.519000, 1.496000, 1.432500, 1.323000, 1.142062, 0.932000, 0.719062, 0.526000,
            0.388125, 0.294000, 0.253313, 0.238000, 0.221438, 0.209000, 0.194813, 0.186000,
            0.192063, 0.200000, 0.198063, 0.192000, 0.182000, 0.173000, 0.172625, 0.173000,
            0.166688, 0.160000, 0.158500, 0.157000, 0.151063, 0.144000, 0.137313, 0.132000,
            0.130250, 0.130000, 0.129938, 0.130000, 0.130063, 0.129000, 0.124375, 0.120000,
            0.119313, 0.121000, 0.125500, 0.131000, 0.136125, 0.140000, 0.140063, 0.140000,
            0.144313, 0.148000, 0.145875, 0.143000, 0.142563, 0.145000, 0.151938, 0.163000],
           [1.080000, 0.882000, 0.761063, 0.647000, 0.550875, 0.504000, 0.554375, 0.663000,
            0.818563, 0.986000, 1.120687, 1.240000, 1.345250, 1.440000, 1.533750, 1.610000,
            1.641875, 1.670000, 1.735000, 1.810000, 1.878750, 1.950000, 2.029375, 2.110000,
            2.186250, 2.260000, 2.329375, 2.400000, 2.478750, 2.560000, 2.640000, 2.720000,
            2.798125, 2.880000, 2.973750, 3.070000, 3.159375, 3.250000, 3.348125, 3.450000,
            3.553750, 3.660000, 3.766250, 3.880000, 4.010625, 4.150000, 4.293125, 4.440000,
            4.586250, 4.740000, 4.908125, 5.090000, 5.288750, 5.500000, 5.720624, 5.950000]),
    "Al": ([0.273375, 0.280000, 0.286813, 0.294000, 0.301875, 0.310000, 0.317875, 0.326000,
            0.334750, 0.344000, 0.353813, 0.364000, 0.374375, 0.385000, 0.395750, 0.407000,
            0.419125, 0.432000, 0.445688, 0.460000, 0.474688, 0.490000, 0.506188, 0.523000,
            0.540063, 0.558000, 0.577313, 0.598000, 0.620313, 0.644000, 0.668625, 0.695000,
            0.723750, 0.755000, 0.789000, 0.826000, 0.867000, 0.912000, 0.963000, 1.020000,
            1.080000, 1.150000, 1.220000, 1.300000, 1.390000, 1.490000, 1.600000, 1.740000,
            1.910000, 2.140000, 2.410000, 2.630000, 2.800000, 2.740000, 2.580000, 2.240000],
           [3.593750, 3.640000, 3.689375, 3.740000, 3.789375, 3.840000, 3.894375, 3.950000,
            4.005000, 4.060000, 4.113750, 4.170000, 4.233750, 4.300000, 4.365000, 4.430000,
            4.493750, 4.560000, 4.633750, 4.710000, 4.784375, 4.860000, 4.938125, 5.020000,
            5.108750, 5.200000, 5.290000, 5.380000, 5.480000, 5.580000, 5.690000, 5.800000,
            5.915000, 6.030000, 6.150000, 6.280000, 6.420000, 6.550000, 6.700000, 6.850000,
            7.000000, 7.150000, 7.310000, 7.480000, 7.650000, 7.820000, 8.010000, 8.210000,
            8.390000, 8.570000, 8.620000, 8.600000, 8.450000, 8.310000, 8.210000, 8.210000]),
    "Au": ([1.795000, 1.812000, 1.822625, 1.830000, 1.837125, 1.840000, 1.834250, 1.824000,
            1.812000, 1.798000, 1.782000, 1.766000, 1.752500, 1.740000, 1.727625, 1.716000,
            1.705875, 1.696000, 1.684750, 1.674000, 1.666000, 1.658000, 1.647250, 1.636000,
            1.628000, 1.616000, 1.596250, 1.562000, 1.502125, 1.426000, 1.345875, 1.242000,
            1.086750, 0.916000, 0.754500, 0.608000, 0.491750, 0.402000, 0.345500, 0.306000,
            0.267625, 0.236000, 0.212375, 0.194000, 0.177750, 0.166000, 0.161000, 0.160000,
            0.160875, 0.164000, 0.169500, 0.176000, 0.181375, 0.188000, 0.198125, 0.210000],
           [1.920375, 1.920000, 1.918875, 1.916000, 1.911375, 1.904000, 1.891375, 1.878000,
            1.868250, 1.860000, 1.851750, 1.846000, 1.845250, 1.848000, 1.852375, 1.862000,
            1.883000, 1.906000, 1.922500, 1.936000, 1.947750, 1.956000, 1.959375, 1.958000,
            1.951375, 1.940000, 1.924500, 1.904000, 1.875875, 1.846000, 1.814625, 1.796000,
            1.797375, 1.840000, 1.956500, 2.120000, 2.326250, 2.540000, 2.730625, 2.880000,
            2.940625, 2.970000, 3.015000, 3.060000, 3.070000, 3.150000, 3.445812, 3.800000,
            4.087687, 4.357000, 4.610188, 4.860000, 5.125813, 5.390000, 5.631250, 5.880000]),
    "Cu": ([1.400313, 1.380000, 1.358438, 1.340000, 1.329063, 1.325000, 1.332500, 1.340000,
            1.334375, 1.325000, 1.317812, 1.310000, 1.300313, 1.290000, 1.281563, 1.270000,
            1.249062, 1.225000, 1.200000, 1.180000, 1.174375, 1.175000, 1.177500, 1.180000,
            1.178125, 1.175000, 1.172812, 1.170000, 1.165312, 1.160000, 1.155312, 1.150000,
            1.142812, 1.135000, 1.131562, 1.120000, 1.092437, 1.040000, 0.950375, 0.826000,
            0.645875, 0.468000, 0.351250, 0.272000, 0.230813, 0.214000, 0.209250, 0.213000,
            0.216250, 0.223000, 0.236500, 0.250000, 0.254188, 0.260000, 0.280000, 0.300000],
           [1.662125, 1.687000, 1.703313, 1.720000, 1.744563, 1.770000, 1.791625, 1.810000,
            1.822125, 1.834000, 1.851750, 1.872000, 1.894250, 1.916000, 1.931688, 1.950000,
            1.972438, 2.015000, 2.121562, 2.210000, 2.177188, 2.130000, 2.160063, 2.210000,
            2.249938, 2.289000, 2.326000, 2.362000, 2.397625, 2.433000, 2.469187, 2.504000,
            2.535875, 2.564000, 2.589625, 2.605000, 2.595562, 2.583000, 2.576500, 2.599000,
            2.678062, 2.809000, 3.010750, 3.240000, 3.458187, 3.670000, 3.863125, 4.050000,
            4.239563, 4.430000, 4.619563, 4.817000, 5.034125, 5.260000, 5.485625, 5.717000]),
}

# Johnson & Christy (1974) via refractiveindex.info: wavelength in micrometres, n, k (visible part).
JC_UM = [0.332, 0.342, 0.354, 0.368, 0.381, 0.397, 0.413, 0.431, 0.451, 0.471, 0.496, 0.521,
         0.549, 0.582, 0.617, 0.659, 0.704, 0.756, 0.821, 0.892]
JC = {
    "Cr": ([1.69, 1.76, 1.84, 1.87, 1.92, 2.00, 2.08, 2.19, 2.33, 2.51, 2.75, 2.94, 3.18, 3.22,
            3.17, 3.09, 3.05, 3.08, 3.20, 3.30],
           [2.53, 2.58, 2.64, 2.69, 2.74, 2.83, 2.93, 3.04, 3.14, 3.24, 3.30, 3.33, 3.33, 3.30,
            3.30, 3.34, 3.39, 3.42, 3.48, 3.52]),
    "Ni": ([1.84, 1.78, 1.74, 1.70, 1.72, 1.72, 1.70, 1.71, 1.73, 1.78, 1.82, 1.85, 1.92, 1.96,
            1.99, 1.99, 2.06, 2.13, 2.26, 2.40],
           [2.22, 2.26, 2.32, 2.40, 2.48, 2.57, 2.69, 2.82, 2.95, 3.09, 3.25, 3.42, 3.61, 3.80,
            4.02, 4.26, 4.50, 4.73, 4.97, 5.23]),
    "Ti": ([1.61, 1.72, 1.82, 1.90, 1.99, 2.08, 2.14, 2.21, 2.27, 2.32, 2.36, 2.44, 2.54, 2.60,
            2.67, 2.76, 2.86, 3.00, 3.21, 3.29],
           [2.74, 2.82, 2.87, 2.90, 2.93, 2.95, 2.98, 3.01, 3.04, 3.10, 3.19, 3.30, 3.43, 3.58,
            3.72, 3.84, 3.96, 4.01, 4.01, 3.96]),
}


def interp(ls, vs, l):
    if l <= ls[0]:
        return vs[0]
    for i in range(1, len(ls)):
        if l <= ls[i]:
            t = (l - ls[i - 1]) / (ls[i] - ls[i - 1])
            return vs[i - 1] + t * (vs[i] - vs[i - 1])
    return vs[-1]


def lobe(l, mu, s1, s2):
    t = (l - mu) / (s1 if l < mu else s2)
    return math.exp(-0.5 * t * t)


def cie_xyz(l):  # Wyman, Sloan & Shirley 2013, eq. 2 (multi-lobe fit of CIE 1931 2-degree)
    x = (1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7)
         - 0.065 * lobe(l, 501.1, 20.4, 26.2))
    y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1)
    z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8)
    return (x, y, z)


M = [(3.2404542, -1.5371385, -0.4985314), (-0.9692660, 1.8760108, 0.0415560),
     (0.0556434, -0.2040259, 1.0572252)]


def xyz_to_srgb(c):
    return tuple(sum(M[i][j] * c[j] for j in range(3)) for i in range(3))


LAMBDAS = list(range(380, 781))


def weights(l):
    return tuple(max(0.0, v) for v in xyz_to_srgb(cie_xyz(l)))


def reduce_rgb(f):
    out = []
    for c in range(3):
        num = sum(f(l) * weights(l)[c] for l in LAMBDAS)
        den = sum(weights(l)[c] for l in LAMBDAS)
        out.append(num / den)
    return out


def fresnel(n, k, c):
    """Exact unpolarised Fresnel reflectance of a conductor (eta = n + i k) at cosine c."""
    s2 = 1.0 - c * c
    t = n * n - k * k - s2
    a2b2 = math.sqrt(t * t + 4.0 * n * n * k * k)
    a = math.sqrt(max(0.0, 0.5 * (a2b2 + t)))
    t1, t2 = a2b2 + c * c, 2.0 * a * c
    rs = (t1 - t2) / (t1 + t2)
    t3, t4 = a2b2 * c * c + s2 * s2, t2 * s2
    return 0.5 * (rs + rs * (t3 - t4) / (t3 + t4))


ANGLES = [(i + 0.5) * 90.0 / 32 for i in range(32)]
WEIGHTS = [math.cos(math.radians(t)) * math.sin(math.radians(t)) for t in ANGLES]


def target_curves(fn, fk):
    """Per angle: the sRGB colour of the spectral reflectance, capped at its spectral maximum."""
    white = [sum(cie_xyz(l)[i] for l in LAMBDAS) for i in range(3)]
    out = []
    for t in ANGLES:
        c = math.cos(math.radians(t))
        xyz = [0.0, 0.0, 0.0]
        top = 0.0
        for l in LAMBDAS:
            cc = cie_xyz(l)
            r = fresnel(fn(l), fk(l), c)
            top = max(top, r)
            for i in range(3):
                xyz[i] += cc[i] * r
        xyz = [v / white[1] for v in xyz]
        xyz[0] *= 0.9505 * white[1] / white[0]  # von Kries to D65: reflectance 1 maps to white
        xyz[2] *= 1.0890 * white[1] / white[2]
        out.append([min(v, top) for v in xyz_to_srgb(xyz)])
    return out


def nelder_mead(f, x0, step=0.1, iterations=400):
    pts = [list(x0), [x0[0] + step, x0[1]], [x0[0], x0[1] + step]]
    vals = [f(p) for p in pts]
    for _ in range(iterations):
        order = sorted(range(3), key=lambda i: vals[i])
        pts, vals = [pts[i] for i in order], [vals[i] for i in order]
        c = [(pts[0][j] + pts[1][j]) / 2 for j in range(2)]
        r = [2 * c[j] - pts[2][j] for j in range(2)]
        fr = f(r)
        if fr < vals[0]:
            e = [3 * c[j] - 2 * pts[2][j] for j in range(2)]
            fe = f(e)
            pts[2], vals[2] = (e, fe) if fe < fr else (r, fr)
        elif fr < vals[1]:
            pts[2], vals[2] = r, fr
        else:
            h = [(c[j] + pts[2][j]) / 2 for j in range(2)]
            fh = f(h)
            if fh < vals[2]:
                pts[2], vals[2] = h, fh
            else:
                for i in (1, 2):
                    pts[i] = [(pts[0][j] + pts[i][j]) / 2 for j in range(2)]
                    vals[i] = f(pts[i])
    return pts[0], vals[0]


def fit_channel(curves, c, start):
    def cost(p):
        n, k = p
        if not (0.01 <= n <= 8.0 and 0.0 <= k <= 15.0):
            return 1e9
        return sum(w * (fresnel(n, k, math.cos(math.radians(t))) - tc[c]) ** 2
                   for t, w, tc in zip(ANGLES, WEIGHTS, curves))
    p, v = nelder_mead(cost, start)
    return p, math.sqrt(v / sum(WEIGHTS))


def main():
    table = []
    for name, (eta, k) in PBRT.items():
        table.append((name, lambda l, e=eta: interp(PBRT_L, e, l),
                      lambda l, kk=k: interp(PBRT_L, kk, l), "Palik (pbrt-v4)"))
    for name, (eta, k) in JC.items():
        ls = [1000.0 * u for u in JC_UM]
        table.append((name, lambda l, e=eta, ls=ls: interp(ls, e, l),
                      lambda l, kk=k, ls=ls: interp(ls, kk, l), "Johnson & Christy 1974"))
    for name, fn, fk, src in sorted(table):
        curves = target_curves(fn, fk)
        e0, k0 = reduce_rgb(fn), reduce_rgb(fk)
        fits = [fit_channel(curves, c, [e0[c], k0[c]]) for c in range(3)]
        e = [p[0] for p, _ in fits]
        kk = [p[1] for p, _ in fits]
        print('    {"%s", vec3(%.4ff, %.4ff, %.4ff), vec3(%.4ff, %.4ff, %.4ff)},  // %s'
              % (name, *e, *kk, src))
        print("    //   F0 %.3f %.3f %.3f (target %.3f %.3f %.3f), rms %.4f %.4f %.4f"
              % (*[fresnel(e[c], kk[c], 1.0) for c in range(3)], *curves[0],
                 *[r for _, r in fits]))


if __name__ == "__main__":
    main()
