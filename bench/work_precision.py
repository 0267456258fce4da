"""Run time against error: every solver family on every accuracy test with a known answer.

    .venv/bin/python bench/work_precision.py [--quick] [--only TEST ...] [--out DIR]

For each test the error against the analytic answer is measured together with the CPU time
(process time, one thread, numba kernels loaded first as a long run would) while the time
step factor, the resolution (A/DX, xi, points per wavelength) and the scheme vary:

  drag          sphere A under a constant force in a periodic cubic array, FIX_CELL on:
                steady V_x against Hasimoto's periodic drag (Sangani-Acrivos series),
                run until V changes by < 5e-4 relatively over one slowest-mode decay time
                L^2/(4 pi^2 nu) (the criterion of tests/validation/test_spm_validation.py);
  rotation      constant torque on the same sphere: steady Omega_z against the periodic
                rotlet result (1 - c - 1.95708 c^(10/3)) T / (8 pi eta A^3);
  taylor_green  2D Taylor-Green vortex (Re = U / (nu k) = 1) in a 3D box, no particles:
                max |u - u0 exp(-2 nu k^2 t)| / max|u| at t = 1 / (2 nu k^2) (decay by 1/e);
  spinodal      linearised Cahn-Hilliard (Landau a = b = kappa = alpha = 1, psi0 = 0):
                growth rate of a cos(k x) mode with k^2 = 1/4, from the amplitude between
                t = T/2 and T = 2 / omega, against omega = -kappa k^2 (f'' + alpha k^2) of the
                continuous equation (so the lattice K^2 and the time scheme both count);
  lees_edwards  free sphere at the shear origin of a Lees-Edwards (oblique frame) flow,
                gamma_dot A^2 / nu = 0.18, to strain 1 (one frame re-mapping): Omega_z
                averaged over strain 0.5..1 against -gamma_dot / 2 (Stokes flow; the spin
                of a sphere at this Reynolds number is lower by ~0.3 %).

The dt factor f is the time step in units of RHO DX^2 / (ETA pi^2) (tests' measured_dt, close
to the automatic time step of a run: kapsel.timestep.auto_dt is 0.7 of it at factor 1); for
the Cahn-Hilliard test f is in units of the explicit scheme's stability limit (stable_dt).

Output: the table on stdout (test, scheme, settings, error, CPU s), the cheapest setting that
reaches 1 % and 5 % per test (and per scheme), and under --out (default bench/results/):
work_precision.csv and one log-log PNG per test (error against CPU s, colour per scheme, a
line through each dt series).  --quick runs one small case per test and scheme (a smoke
run, < 1 min); --only runs the named tests and replaces their rows in an existing CSV.
"""
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")       # as kapsel.cli: BLAS threads only slow BiCGSTAB

import argparse  # noqa: E402
import csv  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from kapsel.mesh import compiled  # noqa: E402
from kapsel.fluid.mac import MACSolver  # noqa: E402
from kapsel.fluid.oblique import ObliqueMAC, ObliqueSpectralNS  # noqa: E402
from kapsel.frame import ShearFlow  # noqa: E402
from kapsel.fluid.spectral import SpectralNS  # noqa: E402
from kapsel.mesh.grid import Grid  # noqa: E402
from kapsel.models.fdm import _ModelH_SPM  # noqa: E402
from kapsel.particles.spm import SPM  # noqa: E402
from kapsel.particles.state import ParticleState  # noqa: E402

RHO = ETA = 1.0
NU = ETA / RHO
TESTS = ("drag", "rotation", "taylor_green", "spinodal", "lees_edwards")
# the NS_solver of the input (Navier_Stokes: spectral; *_FDM: NS_solver.type)
FLUIDS = ("spectral", "MAC explicit", "MAC implicit")


def measured_dt(factor, dx):
    """factor RHO DX^2 / (ETA pi^2): the tests' measured_dt."""
    return factor * RHO / (ETA * (np.pi / dx) ** 2)


# ------------------------------------------------------------------------- fluids + SPM
def rect_spm(kind, shape, dt, particles, A, xi, forces=None):
    """SPM on the spectral solver or on the MAC one as the FDM model builds it (FIX_CELL on:
    the mean velocity removed after each fluid step)."""
    if kind == "spectral":
        fluid = SpectralNS(Grid(shape, 1.0), RHO, ETA, dt, fix_cell=(True, True, True))
        return SPM(fluid, particles, A, xi, RHO, 1.0, dt, forces=forces)
    scheme = {"MAC explicit": "explicit_scheme", "MAC implicit": "implicit_scheme"}[kind]
    fluid = MACSolver(Grid(shape, 1.0), RHO, ETA, dt, scheme=scheme)
    fluid.check_stability()
    spm = _ModelH_SPM(fluid, particles, A, xi, RHO, 1.0, dt, forces=forces)
    spm.fix_cell = (True, True, True)
    return spm


def one_sphere(A, centre):
    p = ParticleState.spheres([0], [A], [1.0], 1.0)
    p.R[0] = centre
    p.R_raw[:] = p.R
    return p


def hasimoto_K(A, L):
    c = 4 / 3 * np.pi * A ** 3 / L ** 3
    return 1.0 / (1 - 1.7601 * c ** (1 / 3) + c - 1.5593 * c ** 2 + 3.9799 * c ** (8 / 3)
                  - 3.0734 * c ** (10 / 3))


def steady(spm, value, every, t_max, tol=5e-4):
    """Run until value() changes by < tol relatively over ``every`` steps (or t_max)."""
    prev = None
    while spm.step_index * spm.dt < t_max:
        spm.run(every)
        v = value()
        if not np.isfinite(v):
            raise FloatingPointError("non-finite particle velocity")
        if prev is not None and abs(v - prev) < tol * abs(v):
            break
        prev = v
    return v


def drag(kind, L, A, xi, factor):
    """V_x / V_Hasimoto - 1 of a sphere pulled by F = (1, 0, 0)."""
    dt = measured_dt(factor, 1.0)
    p = one_sphere(A, [L / 2 + 0.3, L / 2 + 0.2, L / 2 - 0.3])
    F, T = np.array([[1.0, 0.0, 0.0]]), np.zeros((1, 3))
    spm = rect_spm(kind, (L,) * 3, dt, p, A, xi, forces=lambda q: (F, T))
    tau = L ** 2 / (4 * np.pi ** 2 * NU)
    v = steady(spm, lambda: p.v[0, 0], max(1, round(tau / dt)), 12 * tau)
    return v * 6 * np.pi * ETA * A * hasimoto_K(A, L) - 1.0


def rotation(kind, L, A, xi, factor):
    """Omega_z / Omega_rotlet - 1 of a sphere turned by T = (0, 0, 1)."""
    dt = measured_dt(factor, 1.0)
    p = one_sphere(A, [L / 2 + 0.3, L / 2 + 0.2, L / 2 - 0.3])
    F, T = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    spm = rect_spm(kind, (L,) * 3, dt, p, A, xi, forces=lambda q: (F, T))
    c = 4 / 3 * np.pi * A ** 3 / L ** 3
    W = (1 - c - 1.95708 * c ** (10 / 3)) / (8 * np.pi * ETA * A ** 3)
    w = steady(spm, lambda: p.omega[0, 2], max(1, round(A ** 2 / NU / dt)), 40 * A ** 2 / NU)
    return w / W - 1.0


# ------------------------------------------------------------------------- Taylor-Green
def taylor_green(kind, n, factor, box=32.0):
    """max |u - exact| / U at t = 1/(2 nu k^2); kind: 'spectral etd1|etd2', 'MAC ...'."""
    dx = box / n
    k = 2 * np.pi / box
    U = NU * k                                   # Re = U / (nu k) = 1
    x = np.arange(n) * dx
    X, Y = np.meshgrid(x, x, indexing="ij")
    u0 = np.zeros((3, n, n, n))
    u0[0] = (U * np.sin(k * X) * np.cos(k * Y))[:, :, None]
    u0[1] = (-U * np.cos(k * X) * np.sin(k * Y))[:, :, None]
    T = 1.0 / (2 * NU * k * k)
    nsteps = max(1, math.ceil(T / measured_dt(factor, dx)))
    dt = T / nsteps
    if kind.startswith("spectral"):
        ns = SpectralNS(Grid((n,) * 3, dx), RHO, ETA, dt, scheme=kind.split()[1])
        ns.set_velocity(u0)
        ns.run(nsteps)
        u = ns.velocity()
    else:
        scheme = {"MAC explicit": "explicit_scheme", "MAC implicit": "implicit_scheme"}[kind]
        s = MACSolver(Grid((n,) * 3, dx), RHO, ETA, dt, scheme=scheme)
        s.check_stability()
        u = u0.copy()
        for _ in range(nsteps):
            s.step(u)
    return float(np.abs(u - u0 * math.exp(-2 * NU * k * k * T)).max() / U)


# ------------------------------------------------------------------------- spinodal
def spinodal(scheme, n, factor, waves=2):
    """Measured growth rate / continuous omega - 1 of cos(k x), k^2 = 1/4, on (n, 8, 8)
    nodes; n / waves points per wavelength; dt = factor x the explicit stability limit."""
    from kapsel.config import PhaseField
    from kapsel.phase import CahnHilliard
    k = 0.5
    box = waves * 2 * np.pi / k
    dx = box / n
    shape = (n, 8, 8)
    kw = dict(tolerance=1e-10, maximum_iteration=1000, potential="Landau",
              composition_ratio=0.0, initial_fluctuation=0.0, d=0.0, w=0.0, alpha=1.0,
              kappa=1.0, a=1.0, b=1.0)
    psi = np.zeros(shape)
    limit = CahnHilliard(Grid(shape, dx), PhaseField(ch_solver="explicit_scheme", **kw),
                         1.0).stable_dt(psi)
    omega = -1.0 * k * k * (-1.0 + 1.0 * k * k)             # kappa k^2 (a - alpha k^2)
    T = 2.0 / omega
    nsteps = 2 * max(1, math.ceil(T / 2 / (factor * limit)))
    dt = T / nsteps
    ch = CahnHilliard(Grid(shape, dx), PhaseField(ch_solver=scheme, **kw), dt,
                      preconditioner="fft" if scheme == "implicit_scheme" else None)
    c = np.cos(k * np.arange(n) * dx)[:, None, None] * np.ones(shape)
    psi += 1e-8 * c
    amp = []
    for i in range(nsteps):
        ch.step(psi)
        if i + 1 in (nsteps // 2, nsteps):
            amp.append(float(np.mean(psi * c)))
    rate = math.log(amp[1] / amp[0]) / (T / 2)
    return rate / omega - 1.0


# ------------------------------------------------------------------------- Lees-Edwards
def lees_edwards(kind, shape, A, factor, rate=0.02, interpolation="linear", xi=2.0):
    """Mean Omega_z over strain 0.5..1 / (-rate / 2) - 1, free sphere at the shear origin."""
    T = 1.0 / rate
    nsteps = 2 * max(1, math.ceil(T / 2 / measured_dt(factor, 1.0)))
    dt = T / nsteps
    shear = ShearFlow("DC", rate)
    p = one_sphere(A, np.array(shape, float) / 2 + [0.3, 0.0, 0.0])
    if kind == "spectral":
        fluid = ObliqueSpectralNS(Grid(shape, 1.0), RHO, ETA, dt, shear)
        spm = SPM(fluid, p, A, xi, RHO, 1.0, dt)
    else:
        scheme = {"MAC explicit": "explicit_scheme", "MAC implicit": "implicit_scheme"}[kind]
        fluid = ObliqueMAC(Grid(shape, 1.0), RHO, ETA, dt, shear, scheme=scheme,
                           interpolation=interpolation)
        fluid.check_stability()
        spm = _ModelH_SPM(fluid, p, A, xi, RHO, 1.0, dt)
        spm.fix_cell = (False, True, False)        # forced ON for the sheared types
    spm.run(nsteps // 2)
    w = 0.0
    for _ in range(nsteps // 2):
        spm.step()
        w += p.omega[0, 2]
    if not np.isfinite(w):
        raise FloatingPointError("non-finite particle velocity")
    return w / (nsteps // 2) / (-rate / 2) - 1.0


# ------------------------------------------------------------------------- the plan
def plan(quick):
    """(test, scheme, settings text, callable) rows in the order they run."""
    rows = []

    def add(test, scheme, settings, f, *a, **k):
        rows.append((test, scheme, settings, lambda: f(*a, **k)))

    if quick:
        for kind in FLUIDS:
            add("drag", kind, "L=16 A=4 xi=2 f=1", drag, kind, 16, 4.0, 2.0, 1.0)
            add("rotation", kind, "L=16 A=4 xi=2 f=1", rotation, kind, 16, 4.0, 2.0, 1.0)
        for kind in ("spectral etd1", "spectral etd2", "MAC explicit", "MAC implicit"):
            add("taylor_green", kind, "N=16 f=1", taylor_green, kind, 16, 1.0)
        for s, name in (("explicit_scheme", "CH explicit"), ("implicit_scheme", "CH BDF2")):
            add("spinodal", name, "N=16 (8/wave) f=0.5", spinodal, s, 16, 0.5)
        for kind in FLUIDS:
            add("lees_edwards", kind, "16^3 A=3 f=1", lees_edwards, kind, (16,) * 3, 3.0, 1.0)
        return rows

    # drag and rotation: L = 32, A = 4, xi = 2 (c = 0.0082) is the validation setting and
    # the dt series; A/DX = 3 and 5 at the same volume fraction (L = 24, 40); xi = 1 and 3.
    for test, f in (("drag", drag), ("rotation", rotation)):
        for kind, factors in (("spectral", (1.0, 0.5, 0.25, 0.1)),
                              ("MAC explicit", (1.0, 0.5, 0.25)),
                              ("MAC implicit", (2.0, 1.0, 0.5))):
            for fac in factors:
                add(test, kind, f"L=32 A=4 xi=2 f={fac:g}", f, kind, 32, 4.0, 2.0, fac)
        for xi in (1.0, 3.0):
            add(test, "spectral", f"L=32 A=4 xi={xi:g} f=0.5", f, "spectral", 32, 4.0, xi,
                0.5)
        for fac in (1.0, 0.5):
            add(test, "spectral", f"L=24 A=3 xi=2 f={fac:g}", f, "spectral", 24, 3.0, 2.0, fac)
        add(test, "spectral", "L=40 A=5 xi=2 f=0.5", f, "spectral", 40, 5.0, 2.0, 0.5)
    # Taylor-Green: box 32 (one wavelength), N = 16, 32, 48 points per wavelength
    for kind, factors in (("spectral etd1", (10.0, 1.0)), ("spectral etd2", (10.0,)),
                          ("MAC explicit", (1.0, 0.25)), ("MAC implicit", (10.0, 1.0))):
        for n in (16, 32, 48):
            for fac in factors:
                add("taylor_green", kind, f"N={n} f={fac:g}", taylor_green, kind, n, fac)
    for s, name, factors in (("explicit_scheme", "CH explicit", (0.9, 0.3)),
                             ("implicit_scheme", "CH BDF2", (30.0, 3.0, 0.9))):
        for n in (16, 32, 48):
            for fac in factors:
                add("spinodal", name, f"N={n} ({n // 2}/wave) f={fac:g}", spinodal, s, n,
                    fac)
    for kind, factors in (("spectral", (2.0, 1.0, 0.5)), ("MAC explicit", (1.0, 0.5)),
                          ("MAC implicit", (2.0, 1.0))):
        for fac in factors:
            add("lees_edwards", kind, f"16^3 A=3 f={fac:g}", lees_edwards, kind, (16,) * 3,
                3.0, fac)
    # A/DX = 4.5 and 6 at the same volume fraction and the same particle Reynolds number
    # gamma_dot A^2 / nu = 0.18 (the sphere's spin falls with it: Lin, Peery & Schowalter
    # 1970, 1 - 0.0385 Re^1.5, -1 % at 0.4)
    rate = 0.02 * (3.0 / 4.5) ** 2
    for kind in ("spectral", "MAC explicit"):
        add("lees_edwards", kind, f"24^3 A=4.5 f=1 rate={rate:.4f}", lees_edwards, kind,
            (24,) * 3, 4.5, 1.0, rate=rate)
    add("lees_edwards", "spectral", "32^3 A=6 f=1 rate=0.005", lees_edwards, "spectral",
        (32,) * 3, 6.0, 1.0, rate=0.005)
    # OBL_INT matters only when NX is not a multiple of NY (the re-mapping interpolates);
    # the oblique explicit limit is below f = 1 there (metric terms)
    for obl in ("linear", "spline"):
        add("lees_edwards", "MAC explicit", f"24x16x16 A=3 f=0.5 OBL_INT={obl}", lees_edwards,
            "MAC explicit", (24, 16, 16), 3.0, 0.5, interpolation=obl)
    return rows


# ------------------------------------------------------------------------- output
def cheapest(results, test, level, scheme=None):
    ok = [r for r in results if r["test"] == test and r["error"] is not None
          and abs(r["error"]) <= level and scheme in (None, r["scheme"])]
    return min(ok, key=lambda r: r["cpu"]) if ok else None


def read_csv(path):
    """The rows of a previous work_precision.csv (none if there is none)."""
    if not os.path.exists(path):
        return []
    with open(path, newline="") as fh:
        return [dict(test=r["test"], scheme=r["scheme"], settings=r["settings"],
                     error=float(r["relative_error"]) if r["relative_error"] else None,
                     cpu=float(r["cpu_s"]), note=r["note"]) for r in csv.DictReader(fh)]


def plot(results, test, path):
    """Error against CPU s, log-log: colour = scheme; a line joins the runs that differ only
    in the dt factor f (labelled at their points), the series named at its cheapest point."""
    import re
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter
    rows = [r for r in results if r["test"] == test and r["error"] is not None]
    if not rows:
        return
    fig, ax = plt.subplots(figsize=(6.0, 4.2), dpi=80)
    schemes = list(dict.fromkeys(r["scheme"] for r in rows))
    for i, scheme in enumerate(schemes):
        colour = f"C{i}"
        series = {}
        for r in rows:
            if r["scheme"] == scheme:
                key = re.sub(r"\s*f=\S+", "", r["settings"])
                series.setdefault(key, []).append(r)
        for j, (key, rs) in enumerate(series.items()):
            rs.sort(key=lambda r: r["cpu"])
            x = [max(r["cpu"], 1e-3) for r in rs]
            y = [max(abs(r["error"]), 1e-16) for r in rs]
            ax.loglog(x, y, "osD^v<>"[j % 7], ls="-", lw=0.7, color=colour, ms=4,
                      label=scheme if j == 0 else None)
            for r, xx, yy in zip(rs, x, y):
                m = re.search(r"f=(\S+)", r["settings"])
                if m:
                    ax.annotate(m.group(1), (xx, yy), xytext=(3, 2),
                                textcoords="offset points", fontsize=6, color=colour)
            ax.annotate(key, (x[0], y[0]), xytext=(-4, -9), textcoords="offset points",
                        fontsize=5.5, color=colour, ha="right")
    for level in (0.01, 0.05):
        ax.axhline(level, color="0.6", lw=0.7, ls="--")
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("CPU s (one thread)")
    ax.set_ylabel("|relative error|")
    ax.set_title(f"{test}: error against run time (numbers: dt factor f)", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one small case per test and scheme")
    ap.add_argument("--only", nargs="+", choices=TESTS,
                    help="run only these tests (their rows replace those in an existing CSV)")
    ap.add_argument("--scheme", help="run only the rows whose scheme contains this text")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"),
                    help="directory of the CSV and PNGs (default bench/results)")
    ap.add_argument("--no-plots", action="store_true")
    a = ap.parse_args(argv)
    compiled.enable()                 # as a long run would (kapsel.mesh.compiled)
    rows = [r for r in plan(a.quick) if (not a.only or r[0] in a.only)
            and (not a.scheme or a.scheme in r[1])]
    t_start = time.perf_counter()
    print(f"{'test':13s} {'scheme':14s} {'settings':34s} {'error':>10s} {'CPU s':>8s}")
    results = []
    for test, scheme, settings, run in rows:
        cpu = math.inf
        for _ in range(3):           # runs under 0.5 s: the fastest of three (plans, caches)
            t0 = time.process_time()
            try:
                err, note = run(), ""
            except Exception as e:   # an unstable setting is a result too
                err, note = None, f"{type(e).__name__}: {str(e).splitlines()[0][:60]}"
            cpu = min(cpu, time.process_time() - t0)
            if cpu > 0.5 or err is None:
                break
        results.append(dict(test=test, scheme=scheme, settings=settings, error=err, cpu=cpu,
                            note=note))
        e = f"{100 * err:+9.3g}%" if err is not None else f"{'failed':>10s}"
        print(f"{test:13s} {scheme:14s} {settings:34s} {e} {cpu:8.3f} {note}", flush=True)
    print(f"# total {time.perf_counter() - t_start:.0f} s wall")
    print("\ncheapest setting reaching |error| <= 1 % and <= 5 % (all schemes, then each):")
    for test in dict.fromkeys(r["test"] for r in results):
        for scheme in [None] + list(dict.fromkeys(r["scheme"] for r in results
                                                  if r["test"] == test)):
            for level in (0.01, 0.05):
                r = cheapest(results, test, level, scheme)
                txt = (f"{r['scheme']}, {r['settings']}: {100 * r['error']:+.3g} % in "
                       f"{r['cpu']:.3g} s" if r else "none of the tried settings")
                print(f"  {test:13s} {scheme or 'any':14s} {100 * level:g} %: {txt}")
    os.makedirs(a.out, exist_ok=True)
    csv_path = os.path.join(a.out, "work_precision.csv")
    # --only: the named tests' rows are replaced (with --scheme too: only the rows run)
    ran = {(r["test"], r["scheme"], r["settings"]) if a.scheme else r["test"] for r in results}
    kept = [r for r in read_csv(csv_path)
            if ((r["test"], r["scheme"], r["settings"]) if a.scheme else r["test"]) not in ran
            ] if (a.only or a.scheme) else []
    order = {t: i for i, t in enumerate(TESTS)}
    in_plan = {(t, sch, st): i for i, (t, sch, st, _) in enumerate(plan(a.quick))}
    table = sorted(kept + results, key=lambda r: (
        order[r["test"]], in_plan.get((r["test"], r["scheme"], r["settings"]), math.inf)))
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["test", "scheme", "settings", "relative_error", "cpu_s", "note"])
        for r in table:
            w.writerow([r["test"], r["scheme"], r["settings"],
                        "" if r["error"] is None else f"{r['error']:.6e}", f"{r['cpu']:.3f}",
                        r["note"]])
    if not a.no_plots:
        for test in dict.fromkeys(r["test"] for r in results):
            plot(results, test, os.path.join(a.out, f"work_precision_{test}.png"))
    return results


if __name__ == "__main__":
    main()
