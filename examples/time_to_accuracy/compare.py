"""Time to accuracy on the steel slider-crank: flexsens against Exudyn.

Runs the geometrically exact reference (the co-rotational beam of tests/reference/corotational.rs,
32 elements at 1 us), flexsens on steel_slider_crank.toml at its default tolerances and at
others, and Exudyn (exudyn_slider_crank.py: ANCF cable elements, generalised-alpha) at several
meshes and steps; prints a table of each run's error in the rod's mid-span deflection (the
peak's and the whole history's, relative to the reference's peak) against its CPU seconds
(user + system, the median of --repeat runs), and the fastest run of each code within the
accuracy asked (by default peak within 1 %, history within 5 %).

    pip install exudyn          # once; without it only flexsens is measured
    python3 examples/time_to_accuracy/compare.py [--repeat 5] [--work DIR]

Run from the workspace root; it builds the release binaries it needs with cargo.
"""
import argparse
import csv
import json
import os
import resource
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
DECK = os.path.join(HERE, "steel_slider_crank.toml")

# flexsens: the deck as written (its default tolerances) first, then other tolerances
FLEXSENS_SETTINGS = [
    ("the deck as written (defaults)", []),
    ("correction modes undamped", ['body.rod.correction_damping="proportional"']),
    ("correction modes critically damped", ["body.rod.correction_damping=1.0"]),
    ("atol 1e-7 m", ["analysis.atol=1e-7"]),
    ("atol 1e-6 m", ["analysis.atol=1e-6"]),
    ("free-free, 3 modes", ['body.rod.reference="free-free"', "body.rod.modes=3"]),
    ("free-free, 3 modes, atol 1e-7 m",
     ['body.rod.reference="free-free"', "body.rod.modes=3", "analysis.atol=1e-7"]),
]
# Exudyn: (elements, step)
EXUDYN_SETTINGS = [(4, 2e-4), (8, 5e-4), (8, 2e-4), (8, 1e-4), (16, 1e-4), (16, 5e-5)]


def cpu_of(command, env=None):
    """Runs `command`, returns (its stdout, the CPU seconds it and its children used)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed:\n{done.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return done.stdout, cpu


def load(path):
    with open(path) as f:
        rows = list(csv.reader(f))[1:]
    return {round(float(r[0]) * 1e6): (float(r[1]), float(r[2])) for r in rows}


def errors(run, reference):
    """(peak error, history error) of the mid-span deflection, relative to the reference's
    peak, over the times both have."""
    times = sorted(set(run) & set(reference))
    peak_ref = max(abs(reference[t][0]) for t in reference)
    peak = max(abs(run[t][0]) for t in run)
    history = max(abs(run[t][0] - reference[t][0]) for t in times)
    return abs(peak - peak_ref) / peak_ref, history / peak_ref


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per setting (median CPU)")
    parser.add_argument("--work", default=os.path.join(ROOT, "target", "time_to_accuracy"))
    parser.add_argument("--peak", type=float, default=0.01, help="accuracy asked of the peak")
    parser.add_argument("--history", type=float, default=0.05,
                        help="accuracy asked of the history")
    args = parser.parse_args()
    os.makedirs(args.work, exist_ok=True)

    subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "flexsens",
                    "--example", "slider_crank_reference", "-p", "flexsens-tests"],
                   cwd=ROOT, check=True)
    reference_csv = os.path.join(args.work, "reference.csv")
    if not os.path.exists(reference_csv):
        subprocess.run([os.path.join(ROOT, "target", "release", "examples",
                                     "slider_crank_reference"), reference_csv], check=True)
    reference = load(reference_csv)

    rows = []
    binary = os.path.join(ROOT, "target", "release", "flexsens")
    for label, sets in FLEXSENS_SETTINGS:
        out = os.path.join(args.work, "flexsens-" + str(len(rows)))
        command = [binary, "run", DECK, "-o", out, "--quiet", "--json"]
        for s in sets:
            command += ["--set", s]
        cpus = []
        for _ in range(args.repeat):
            stdout, cpu = cpu_of(command)
            cpus.append(cpu)
        steps = json.loads(stdout.splitlines()[-1])["steps"]
        rows.append(("flexsens", label, steps, statistics.median(cpus), None,
                     *errors(load(os.path.join(out, "history.csv")), reference)))

    try:
        import exudyn  # noqa: F401
        have_exudyn = True
    except ImportError:
        have_exudyn = False
        print("exudyn is not installed (pip install exudyn): flexsens only", file=sys.stderr)
    if have_exudyn:
        script = os.path.join(HERE, "exudyn_slider_crank.py")
        for elements, step in EXUDYN_SETTINGS:
            out = os.path.join(args.work, f"exudyn-{elements}-{step:g}.csv")
            cpus, solver = [], []
            for _ in range(args.repeat):
                stdout, cpu = cpu_of([sys.executable, script, "--elements", str(elements),
                                      "--step", str(step), "--out", out])
                cpus.append(cpu)
                solver.append(json.loads(stdout.splitlines()[-1])["solver_cpu"])
            rows.append(("Exudyn", f"{elements} elements, h = {step:g} s", round(0.1 / step),
                         statistics.median(cpus), statistics.median(solver),
                         *errors(load(out), reference)))

    print(f"| code | setting | steps | CPU s (process) | CPU s (solver) | peak error | "
          f"history error | within {args.peak:g} / {args.history:g} |")
    print("|---|---|---|---|---|---|---|---|")
    for code, label, steps, cpu, solver, peak, history in rows:
        ok = peak <= args.peak and history <= args.history
        solver_text = f"{solver:.3f}" if solver is not None else "—"
        print(f"| {code} | {label} | {steps} | {cpu:.3f} | {solver_text} | {peak:.2e} | "
              f"{history:.2e} | {'yes' if ok else 'no'} |")
    within = [r for r in rows if r[5] <= args.peak and r[6] <= args.history]
    best = {}
    for code, label, steps, cpu, solver, peak, history in within:
        if code not in best or cpu < best[code][1]:
            best[code] = (label, cpu)
    for code, (label, cpu) in best.items():
        print(f"fastest {code} run within the accuracy: {label}, {cpu:.3f} s")
    solvers = [(r[4], r[1]) for r in within if r[4] is not None]
    if solvers:
        solver, label = min(solvers)
        print(f"fastest Exudyn solver within the accuracy: {label}, {solver:.3f} s")
    default = rows[0]
    if "Exudyn" in best:
        exudyn = best["Exudyn"][1]
        for name, cpu in (("at its defaults", default[3]),
                          ("at its fastest within the accuracy", best.get("flexsens", (0, None))[1])):
            if cpu is None:
                print(f"flexsens: no run within the accuracy")
                continue
            text = f"flexsens {name}: {cpu:.3f} s, {exudyn / cpu:.2f}x as fast as Exudyn's process"
            if solvers:
                text += f", {min(solvers)[0] / cpu:.2f}x its solver"
            print(text)

if __name__ == "__main__":
    main()
