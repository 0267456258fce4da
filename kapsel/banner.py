"""What a run will be, in a few lines: the start banner on stderr and ``kapsel-py --check``.

``describe(cfg, args, model, resumed, files)`` gives the lines: type and solvers, mesh and
box, particles, dt and how it was chosen, steps and snapshots, the files and where, threads,
seed.  ``memory_estimate(cfg)`` is the figure the input check budgets with (config.py).
The models do no I/O; this module only formats what the configuration and model hold.
"""
from __future__ import annotations

import math


def _g(x: float) -> str:
    return f"{float(x):.6g}"


def memory_estimate(cfg) -> float:
    """Peak bytes of the run: the figure the input check budgets with (config.py)."""
    from . import config
    p = cfg.particles
    return config.memory_estimate(cfg.mesh, cfg.type, p.count, p.A, p.A_XI)


def _solvers(cfg) -> str:
    parts = []
    if cfg.is_fdm:
        parts.append(f"MAC {cfg.fluid.ns_solver.replace('_scheme', '')}")
    else:
        parts.append("spectral fluid")
    if cfg.phase is not None:
        parts.append(f"Cahn-Hilliard {cfg.phase.ch_solver.replace('_scheme', '')}, "
                     f"{cfg.phase.potential}")
    if cfg.shear is not None:
        parts.append(f"{cfg.shear.kind} shear rate {_g(cfg.shear.shear_rate)}"
                     + (f", frequency {_g(cfg.shear.frequency)}" if cfg.shear.kind == "AC"
                        else ""))
    el = getattr(cfg, "electrolyte", None)
    if el is not None:
        ions = (f"salt z = {_g(el.valency[0])}, {_g(el.valency[1])}, Debye length "
                f"{_g(el.debye_length)}" if el.salt else
                f"salt-free, counterion z = {_g(el.valency[0])}")
        fld = ("no field" if el.field_kind == "OFF" else
               f"{el.field_kind} field ({', '.join(_g(e) for e in el.E)})"
               + (f", frequency {_g(el.frequency)}" if el.field_kind == "AC" else ""))
        import math
        kbt = cfg.fluid.kBT
        bjerrum = (f", Bjerrum length {_g(1.0 / (4 * math.pi * el.dielectric * kbt))}"
                   if kbt > 0 else "")
        parts.append(f"ions: {ions}{bjerrum}, {el.init_profile} start, {fld}")
    return "; ".join(parts)


def _dt(cfg, dt: float) -> str:
    el = getattr(cfg, "electrolyte", None)
    if cfg.time.kind == "auto" and el is not None:
        ac = f", AC Frequency = {_g(el.frequency)}" if el.field_kind == "AC" else ""
        return (f"dt = {_g(dt)} (auto, factor {_g(cfg.time.factor)}, from RHO = "
                f"{_g(cfg.fluid.RHO)}, ETA = {_g(cfg.fluid.ETA)}, kBT = {_g(cfg.fluid.kBT)}, "
                f"Onsager {_g(max(el.onsager))}, DX = {_g(cfg.mesh.DX)}{ac})")
    if cfg.time.kind == "auto":
        return (f"dt = {_g(dt)} (auto, factor {_g(cfg.time.factor)}, from RHO = "
                f"{_g(cfg.fluid.RHO)}, ETA = {_g(cfg.fluid.ETA)}, DX = {_g(cfg.mesh.DX)})")
    return f"dt = {_g(dt)} (given: time_increment.manual.delta_t)"


def _particles(cfg) -> str:
    p = cfg.particles
    if not p.count:
        return "particles: none"
    kinds = {"spherical_particle": "spheres", "chain": "chains", "rigid": "rigid bodies"}
    groups = ", ".join(f"{s.number}" + (f" x {s.beads} beads" if p.object_type != "spherical_particle"
                                        else "")
                       for s in p.species if s.number)
    return (f"particles: {p.count} ({p.object_type}: {groups} {kinds.get(p.object_type, '')}), "
            f"A = {_g(p.A)}, A_XI = {_g(p.A_XI)}")


def _placement(cfg, model) -> list[str]:
    """What the placement left overlapping (kapsel.particles.placement.overlap_note)."""
    note = getattr(getattr(model, "particles", None), "placement_note", None)
    if not note:
        return []
    if cfg.interactions.LJ_truncate == "NONE":
        return [f"placement: {note}; no pair force acts (LJ_truncate NONE): they stay so"]
    return [f"placement: {note}; the pair repulsion separates them"]


def _electric(cfg) -> list[str]:
    """Quincke constraint and dipoles (kapsel.particles.dipoles), with the Ewald split."""
    sw, out = cfg.switches, []
    names = {(1.0, 0.0, 0.0): "X", (0.0, 1.0, 0.0): "Y", (0.0, 0.0, 1.0): "Z"}
    qk, d = sw.quincke, sw.dipoles
    if qk is not None:
        out.append(f"Quincke constraint: field along {names[qk.field_dir]}, body axis "
                   f"{names[qk.body_axis]}, K = {_g(qk.torque_amp)}")
    if d is not None:
        from .particles.ewald import choose_parameters
        n = cfg.particles.count * (2 if d.mirror_z is not None else 1)
        e = choose_parameters(cfg.mesh.box, n, d.tol)
        what = (f"FIXED along body {names[d.axis]}" if d.kind == "FIXED" else
                f"QUINCKE, Pz_factor {_g(d.pz_factor)}, " +
                (f"mirror images in z = {_g(d.mirror_z)}" if d.mirror_z is not None
                 else "no mirror images"))
        surf = "tin-foil" if d.epsilon_surface == float("inf") else \
            f"epsilon {_g(d.epsilon_surface)}"
        out.append(f"dipoles {_g(d.magnitude)} ({what}); Ewald to {d.tol:.2g} ({surf}, "
                   f"alpha {_g(e.alpha)}, r_cut {_g(e.r_cut)}, k_cut {_g(e.k_cut)})")
    return out


def _files(files: list[tuple[str, str]]) -> list[str]:
    """``files``: (directory, what) pairs -> one line per directory."""
    by_dir: dict[str, list[str]] = {}
    for d, what in files:
        by_dir.setdefault(d, []).append(what)
    return [f"writes in {d}: {', '.join(whats)}" for d, whats in by_dir.items()]


def describe(cfg, args, model, resumed: bool, files: list[tuple[str, str]],
             seed_drawn: bool = False) -> list[str]:
    """The lines of the banner (no leading '#')."""
    nx, ny, nz = cfg.mesh.shape
    bx, by, bz = (_g(x) for x in cfg.mesh.box)
    total = cfg.output.total_steps
    dt = model.dt
    lines = [f"kapsel-py: {cfg.type} ({_solvers(cfg)})",
             f"mesh {nx} x {ny} x {nz}, DX = {_g(cfg.mesh.DX)}, box {bx} x {by} x {bz}",
             _particles(cfg), *_placement(cfg, model), *_electric(cfg),
             _dt(cfg, dt)]
    if getattr(model, "spm_drag", "original") != "original" and cfg.particles.count:
        lines.append(f"SPM drag {model.spm_drag}: profile radius {model.spm.stencil.A:.4f} "
                     f"(hydrodynamic radius A = {_g(cfg.particles.A)})")
    if resumed:
        lines.append(f"continues from step {model.step_index} (t = {_g(model.time)}) to step "
                     f"{total}: {max(total - model.step_index, 0)} steps, a snapshot every "
                     f"{cfg.output.GTS} steps" + (", then one step more for the restart"
                                                  if model.step_index <= total else ""))
    else:
        lines.append(f"{total} steps to t = {_g(total * dt)}: {cfg.output.Num_snap} snapshots "
                     f"every {cfg.output.GTS} steps (plus the initial state), then one step "
                     f"more for the restart (as the original)")
    lines += _files(files)
    lines += model.dist.describe()        # the division of work (kapsel.parallel)
    seed = f"seed {args.seed}" + (f" (drawn; rerun with --seed {args.seed} to reproduce)"
                                  if seed_drawn else "")
    lines.append(f"threads {args.threads}, {seed}")
    return lines


def print_banner(lines, stream, prefix: str = "#") -> None:
    for line in lines:
        print(f"{prefix}{line}", file=stream)
    stream.flush()
