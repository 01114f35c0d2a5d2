#!/usr/bin/env python3
"""Measurements on the original thesis engine (LukasEngedal/Deep-Contact at a4097e51, its
modified pybox2d 2.3.2), for docs/THESIS.md. Drives the original code; copies none of it.

Build the original as ../shared/thesis_original/README.md says, then, from the project root:

    PY=/work/scratch/venv/bin/python; ORIG=/work/scratch/Deep-Contact
    $PY docs/thesis_original/probe.py --repo $ORIG --out DIR timing
    $PY docs/thesis_original/probe.py --repo $ORIG --out DIR chaos --perturbations 10
    $PY docs/thesis_original/probe.py --repo $ORIG --out DIR copy --methods copy2,twin2 [--perturb P]
    $PY docs/thesis_original/probe.py --repo $ORIG --out DIR order

Options before the subcommand: --round-start (start a float64 build of the engine from the
float32 worlds), --no-skin (the box's chain loop moved out by its 1 mm skin), --edges (the
box as four separate edges, surface at the walls) and --mirror (every world's mirror image,
x -> 15 - x; the nudge of `chaos` is applied after mirroring, and the scene files it writes are
the mirrored worlds).

Subcommands:

timing  ms per step of each method on the ten worlds, timed as the thesis's run_world times
        a step (model.Step + world.Step + ClearForces), in wall and in this process's CPU
        time (the CPU time is what a busy machine leaves comparable).
chaos   the ten worlds with circle p's x moved by one float32 ulp (p = 1..N; p = 0 is the
        unperturbed world), none and builtin: the builtin/none ratio per perturbation, and
        the step at which each perturbed trajectory leaves the unperturbed one (largest
        position difference > 1e-3 m, and the first step whose iteration count differs).
        Also writes the perturbed worlds as scene files (world,seed,body_index,x,y,radius)
        for our engine (`--scene file:PATH`).
copy    the original CopyWorldModel (`copyN`: a fresh copy of the world, solved cold, rounded
        to N decimals; `copy` unrounded) beside `twinN`: the same oracle, but solved by a twin
        world that is created with the world and kept on the world's state every step (its
        bodies set to the world's after each step), so its contacts were created in the
        same history and are swept in (nearly) the world's own island order. The fraction of
        steps whose twin island order equals the world's is reported.
order   how Box2D v2.3's island sweep order (the order b2Island reports contacts to
        PostSolve) compares with our engine's problem order (pairs sorted by body index,
        grouped by island) and with a fresh copy's order: normalised Kendall distance
        (fraction of contact pairs in the opposite order; 0 same order, 0.5 unrelated).
"""
import argparse
import csv
import json
import os
import sys
import time

import numpy as np

# run_model.py's parameters (as ../shared/thesis_original/run_original.py)
N_WORLDS = 10
N_BODIES = 100
SIGMA = 1.2
LOW, HIGH = (0, 0), (15, 15)
RADIUS = (0.5, 0.5)
SEEDS = list(range(12345, 12345 + N_WORLDS))
DT = 1.0 / 100
VEL_ITERS = 1000
POS_ITERS = 250
VEL_THR = 1e-4
POS_THR = 1e-4
STEPS = 250


def load(repo):
    sys.path.insert(0, os.path.abspath(repo))
    import Box2D
    from Box2D import b2World, b2Vec2, b2ContactListener
    from src.gen_world import new_confined_clustered_circles_world
    import src.performance.models as models
    import src.performance.util as util
    return dict(Box2D=Box2D, b2World=b2World, b2Vec2=b2Vec2, listener=b2ContactListener,
                gen=new_confined_clustered_circles_world, models=models, util=util)


def new_world(o, seed):
    w = o["b2World"]()
    o["gen"](w, N_BODIES, o["b2Vec2"](*LOW), o["b2Vec2"](*HIGH), RADIUS, SIGMA, seed)
    if o["round_start"]:
        # a float64 build of the engine keeps numpy's doubles: start from the float32 worlds
        for b in w.bodies:
            if b.userData.id != 0:
                b.position = o["b2Vec2"](float(np.float32(b.position.x)),
                                         float(np.float32(b.position.y)))
    if o.get("mirror"):
        # the world's mirror image x -> 15 - x (the box is symmetric): every rule of both
        # engines is mirror-symmetric except the stop rule's max(0, friction change)
        for b in w.bodies:
            if b.userData.id != 0:
                b.position = o["b2Vec2"](HIGH[0] + LOW[0] - b.position.x, b.position.y)
    return w


def make_model(o, name):
    m = o["models"]
    fixed = {
        "none": m.NoWarmStartModel, "builtin": m.BuiltinWarmStartModel, "bad": m.BadModel,
        "copy": m.CopyWorldModel,
    }
    if name in fixed:
        return fixed[name]()
    if name == "random":
        return m.RandomModel(0)
    if name.startswith("copy"):
        return m.CopyWorldModel(int(name[4:]))
    if name.startswith("twin"):
        return twin_model(o, None if name == "twin" else int(name[4:]))
    raise SystemExit("unknown method " + name)


def setup(world, model):
    # run_world's set-up
    world.convergenceRates = True
    world.velocityThreshold = VEL_THR
    world.positionThreshold = POS_THR
    world.contactListener = model


def step(world, model):
    """One step as run_world takes it; returns (vel its, pos its, contacts)."""
    model.Step(world, DT, VEL_ITERS, POS_ITERS)
    world.Step(DT, VEL_ITERS, POS_ITERS)
    world.ClearForces()
    p = world.GetProfile()
    return p.maxIslandVelocityIterations, p.maxIslandPositionIterations, p.contactsSolved


def positions(world):
    return np.array([(b.position.x, b.position.y) for b in world.bodies[1:]], dtype=np.float64)


def ratio(stats):
    return stats["builtin"] / stats["none"]


def contact_mean(V, C):
    V, C = np.asarray(V, float), np.asarray(C, float)
    return float(V[C > 0].mean())


# ---------------------------------------------------------------------------------- timing
def cmd_timing(o, args):
    out = {}
    for method in args.methods.split(","):
        model = make_model(o, method)
        wall, cpu, V, C = [], [], [], []
        for seed in SEEDS:
            world = new_world(o, seed)
            setup(world, model)
            v_, c_ = [], []
            for _ in range(STEPS):
                # run_world's step timer (model.Step + world.Step + ClearForces), in wall
                # and in CPU time of this process
                t, c = time.perf_counter(), time.process_time()
                model.Step(world, DT, VEL_ITERS, POS_ITERS)
                world.Step(DT, VEL_ITERS, POS_ITERS)
                world.ClearForces()
                wall.append(time.perf_counter() - t)
                cpu.append(time.process_time() - c)
                p = world.GetProfile()
                v_.append(p.maxIslandVelocityIterations)
                c_.append(p.contactsSolved)
            V.append(v_)
            C.append(c_)
        out[method] = {
            "wall_ms_per_step": 1e3 * float(np.mean(wall)),
            "cpu_ms_per_step": 1e3 * float(np.mean(cpu)),
            "cpu_seconds_per_2_5s_simulation": float(np.sum(cpu)) / N_WORLDS,
            "mean_iterations_contact_steps": contact_mean(V, C),
        }
        print(method, json.dumps(out[method]), flush=True)
    return out


# ----------------------------------------------------------------------------------- chaos
def nudge(o, world, body_index):
    """Moves circle `body_index`'s x up by one float32 ulp (before the first step)."""
    b = next(b for b in world.bodies if b.userData.id == body_index)
    x = np.float32(b.position.x)
    x1 = np.nextafter(x, np.float32(np.inf))
    b.position = o["b2Vec2"](float(x1), b.position.y)
    assert np.float32(b.position.x) == x1


def run_traj(o, method, seed, perturb):
    model = make_model(o, method)
    world = new_world(o, seed)
    if perturb:
        nudge(o, world, perturb)
    setup(world, model)
    V, C, P = [], [], []
    for _ in range(STEPS):
        v, _, c = step(world, model)
        V.append(v)
        C.append(c)
        P.append(positions(world))
    return np.array(V), np.array(C), np.array(P)


def cmd_chaos(o, args):
    methods = ["none", "builtin"]
    base = {}
    rows = []
    ratios = {}
    div = {m: [] for m in methods}
    it_div = {m: [] for m in methods}
    for p in range(args.perturbations + 1):
        means = {}
        for m in methods:
            Vs, Cs = [], []
            for w, seed in enumerate(SEEDS):
                V, C, P = run_traj(o, m, seed, p)
                Vs.append(V)
                Cs.append(C)
                if p == 0:
                    base[(m, w)] = (V, P)
                else:
                    V0, P0 = base[(m, w)]
                    d = np.abs(P - P0).max(axis=(1, 2))
                    first = int(np.argmax(d > 1e-3)) + 1 if (d > 1e-3).any() else None
                    first_it = int(np.argmax(V != V0)) + 1 if (V != V0).any() else None
                    div[m].append(first)
                    it_div[m].append(first_it)
                    rows.append([p, w + 1, seed, m, first, first_it, float(d[99]), float(d[149]),
                                 float(d[-1])])
            means[m] = contact_mean(Vs, Cs)
            if p == 0 and args.check:
                ref = os.path.join(args.check, "results_%s_per_world.csv" % m)
                with open(ref) as f:
                    r = list(csv.DictReader(f))
                ref_v = np.array([int(x["velocity_iterations"]) for x in r]).reshape(N_WORLDS, STEPS)
                assert np.array_equal(ref_v, np.array(Vs)), "unperturbed run differs from " + ref
        ratios[p] = {"none": means["none"], "builtin": means["builtin"],
                     "ratio": means["builtin"] / means["none"]}
        print("perturbation", p, json.dumps(ratios[p]), flush=True)
        write_scene(o, os.path.join(args.out, "worlds_perturbed_%d.csv" % p), p)
    with open(os.path.join(args.out, "chaos_divergence.csv"), "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["perturbation", "world", "seed", "method", "first_step_dpos_gt_1e-3",
                     "first_step_iterations_differ", "dpos_step100", "dpos_step150",
                     "dpos_step250"])
        wr.writerows(rows)
    pert = [ratios[p]["ratio"] for p in ratios if p > 0]
    summary = {"ratios": ratios,
               "perturbed_ratio_mean": float(np.mean(pert)),
               "perturbed_ratio_sd": float(np.std(pert, ddof=1)),
               "perturbed_ratio_min": float(np.min(pert)),
               "perturbed_ratio_max": float(np.max(pert))}
    for m in methods:
        d = [x for x in div[m] if x is not None]
        summary["divergence_" + m] = {
            "trajectories": len(div[m]), "diverged": len(d),
            "median_step_dpos_gt_1e-3": float(np.median(d)) if d else None,
            "min_step": int(min(d)) if d else None, "max_step": int(max(d)) if d else None,
            "median_first_step_iterations_differ":
                float(np.median([x for x in it_div[m] if x is not None])),
        }
    print(json.dumps(summary, indent=1), flush=True)
    return summary


def write_scene(o, path, perturb):
    with open(path, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["world", "seed", "body_index", "x", "y", "radius"])
        for w, seed in enumerate(SEEDS):
            world = new_world(o, seed)
            if perturb:
                nudge(o, world, perturb)
            for b in world.bodies:
                if b.userData.id == 0:
                    continue
                wr.writerow([w + 1, seed, b.userData.id, repr(b.position.x), repr(b.position.y),
                             repr(b.fixtures[0].shape.radius)])


# ------------------------------------------------------------------------------------ copy
class Recorder:
    """Records the (idA, idB) order of PostSolve calls: b2Island::Report's order, i.e. the
    island sweep order."""

    def __init__(self):
        self.order = []

    def post(self, contact):
        self.order.append((contact.fixtureA.body.userData.id, contact.fixtureB.body.userData.id))


def twin_model(o, accuracy):
    models, util = o["models"], o["util"]

    class Cold(o["listener"]):
        def __init__(self):
            super().__init__()
            self.rec = Recorder()

        def PreSolve(self, contact, _):
            for i in range(contact.manifold.pointCount):
                point = contact.manifold.points[i]
                point.normalImpulse = 0
                point.tangentImpulse = 0

        def PostSolve(self, contact, impulse):
            self.rec.post(contact)

    class Twin(models.Model):
        """CopyWorldModel's oracle, solved by a twin world with the world's history."""

        def __init__(self):
            super().__init__()
            self.accuracy = accuracy
            self.twin = None
            self.seed = None
            self.same_order = 0
            self.steps = 0
            self.rec = Recorder()

        def attach(self, seed, perturb):
            self.seed = seed
            self.twin = new_world(o, seed)
            if perturb:
                nudge(o, self.twin, perturb)
            self.cold = Cold()
            self.twin.convergenceRates = True
            self.twin.velocityThreshold = VEL_THR
            self.twin.positionThreshold = POS_THR
            self.twin.contactListener = self.cold

        def Step(self, world, timeStep, velocityIterations, positionIterations):
            super().Step(world, timeStep, velocityIterations, positionIterations)
            # the twin holds the world's state (set after the previous step)
            self.cold.rec.order = []
            self.twin.Step(timeStep, velocityIterations, positionIterations)
            self.twin.ClearForces()
            for contact in self.twin.contacts:
                res = []
                for p in contact.manifold.points:
                    n, t = p.normalImpulse, p.tangentImpulse
                    if self.accuracy is not None:
                        n, t = round(n, self.accuracy), round(t, self.accuracy)
                    res.append([n, t])
                util.storePredictions(self.predictionDict, contact, res)
            self.rec.order = []

        def PreSolve(self, contact, old):
            super().PreSolve(contact, old)

        def PostSolve(self, contact, impulse):
            super().PostSolve(contact, impulse)
            self.rec.post(contact)

        def sync(self, world):
            """After the world's step: the twin's bodies take the world's state; counts
            whether the twin swept in the world's order this step."""
            self.steps += 1
            self.same_order += self.cold.rec.order == self.rec.order
            for b, t in zip(world.bodies, self.twin.bodies):
                if b.type != 2:  # b2_dynamicBody
                    continue
                t.transform = (b.position, b.angle)
                t.linearVelocity = b.linearVelocity
                t.angularVelocity = b.angularVelocity

    return Twin()


def cmd_copy(o, args):
    out = {}
    for method in args.methods.split(","):
        model = make_model(o, method)
        V, C = [], []
        for seed in SEEDS:
            world = new_world(o, seed)
            if args.perturb:
                nudge(o, world, args.perturb)
            twin = hasattr(model, "attach")
            if twin:
                model.attach(seed, args.perturb)
            setup(world, model)
            v_, c_ = [], []
            for _ in range(STEPS):
                v, _, c = step(world, model)
                if twin:
                    model.sync(world)
                v_.append(v)
                c_.append(c)
            V.append(v_)
            C.append(c_)
        V, C = np.array(V), np.array(C)
        r = {"mean_iterations_contact_steps": contact_mean(V, C),
             "median_iterations_contact_steps": float(np.median(V[C > 0]))}
        if hasattr(model, "attach"):
            r["steps_twin_order_equals_world_order"] = model.same_order / model.steps
        out[method] = r
        name = "copy_%s_p%d_per_world.csv" % (method, args.perturb)
        with open(os.path.join(args.out, name), "w", newline="") as f:
            wr = csv.writer(f)
            wr.writerow(["world", "seed", "step", "velocity_iterations", "contacts"])
            for w in range(N_WORLDS):
                for s in range(STEPS):
                    wr.writerow([w + 1, SEEDS[w], s + 1, V[w, s], C[w, s]])
        print(method, json.dumps(r), flush=True)
    return out


# ----------------------------------------------------------------------------------- order
def kendall(a, b):
    """Normalised Kendall distance between two orders of the same items."""
    pos = {x: i for i, x in enumerate(b)}
    seq = [pos[x] for x in a]
    n = len(seq)
    if n < 2:
        return 0.0
    disc = sum(1 for i in range(n) for j in range(i + 1, n) if seq[i] > seq[j])
    return disc / (n * (n - 1) / 2)


def islands(contacts):
    """Smallest circle of each circle's island (union-find over circle-circle contacts; the
    box joins no island)."""
    parent = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            x = parent[x]
        return x

    for a, b, _, _ in contacts:
        if a != 0:
            ra, rb = find(a), find(b)
            parent[max(ra, rb)] = min(ra, rb)
    return {b: find(b) for _, b, _, _ in contacts} | {a: find(a) for a, _, _, _ in contacts if a}


def cmd_order(o, args):
    """At steps 100, 150, 200 and 250 of each world (builtin): the island order of the world,
    of a fresh copy (CopyWorldModel's) and ours (sorted pairs, grouped by island)."""

    class Rec(o["listener"]):
        def __init__(self):
            super().__init__()
            self.order = []

        def PostSolve(self, contact, impulse):
            self.order.append((contact.fixtureA.body.userData.id,
                               contact.fixtureB.body.userData.id,
                               contact.childIndexA, contact.childIndexB))

    at = {100, 150, 200, 250}
    rows = []
    for w, seed in enumerate(SEEDS):
        world = new_world(o, seed)
        rec = Rec()
        world.velocityThreshold, world.positionThreshold = VEL_THR, POS_THR
        world.contactListener = rec
        for s in range(1, STEPS + 1):
            copy_order = None
            if s in at:
                copy = o["util"].copyWorld(world)
                crec = Rec()
                copy.contactListener = crec
                copy.Step(DT, VEL_ITERS, POS_ITERS)
                copy_order = crec.order
            rec.order = []
            world.Step(DT, VEL_ITERS, POS_ITERS)
            world.ClearForces()
            if s in at:
                mine = rec.order
                # ours: walls (body 0 here, child edge = our wall index) before circles;
                # pairs sorted by (lower body, higher body), grouped by island (stable)
                island = islands(mine)
                key = lambda c: (island[c[1]],) + ((c[0], c[2], c[1]) if c[0] == 0
                                                   else (c[0] + 3, 0, c[1] + 3))
                ours = sorted(mine, key=key)
                common = set(mine) & set(copy_order)
                rows.append({
                    "world": w + 1, "step": s, "contacts": len(mine),
                    "kendall_world_vs_ours": kendall(mine, ours),
                    "kendall_world_vs_fresh_copy": kendall([c for c in mine if c in common],
                                                           [c for c in copy_order if c in common]),
                    "identical_world_vs_fresh_copy": mine == copy_order,
                })
                print(json.dumps(rows[-1]), flush=True)
    summary = {k: float(np.mean([r[k] for r in rows]))
               for k in ("kendall_world_vs_ours", "kendall_world_vs_fresh_copy")}
    summary["rows"] = rows
    return summary


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repo", required=True, help="checkout of LukasEngedal/Deep-Contact")
    ap.add_argument("--out", required=True, help="writable output folder")
    ap.add_argument("--round-start", action="store_true",
                    help="round the initial positions to float32 (for an engine built with "
                         "`typedef double float32`, which would keep numpy's doubles)")
    ap.add_argument("--no-skin", action="store_true",
                    help="move the box's chain loop out by its skin radius (2 x slop), so the "
                         "walls' surface lies at 0 and 15 m as in our engine")
    ap.add_argument("--edges", action="store_true",
                    help="the box as four separate edge fixtures (no chain loop, no ghost "
                         "vertices), their surface at 0 and 15 m as in our engine")
    ap.add_argument("--mirror", action="store_true",
                    help="every world's mirror image x -> 15 - x (before any nudge)")
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("timing")
    t.add_argument("--methods", default="none,builtin,random,bad,copy,copy2,copy0")
    c = sub.add_parser("chaos")
    c.add_argument("--perturbations", type=int, default=10)
    c.add_argument("--check", help="folder of the original's results_<method>_per_world.csv: "
                                   "the unperturbed run must match it")
    k = sub.add_parser("copy")
    k.add_argument("--methods", default="copy,twin,copy2,twin2,copy0,twin0")
    k.add_argument("--perturb", type=int, default=0,
                   help="move circle P's x one float32 ulp up first (0: the thesis worlds)")
    sub.add_parser("order")
    args = ap.parse_args()
    o = load(args.repo)
    o["round_start"] = args.round_start
    o["mirror"] = args.mirror
    if args.no_skin:
        import src.gen_world as gen_world
        box = gen_world.create_fixed_box

        def outward(world, p_ll, p_hr, pos=(0, 0)):
            # the loop's surface (vertices + 2 x slop skin) at the box's walls, as ours
            skin = o["Box2D"].b2_polygonRadius
            box(world, o["b2Vec2"](p_ll[0] - skin, p_ll[1] - skin),
                o["b2Vec2"](p_hr[0] + skin, p_hr[1] + skin), pos)

        gen_world.create_fixed_box = outward
    if args.edges:
        import src.gen_world as gen_world

        def edges(world, p_ll, p_hr, pos=(0, 0)):
            # four separate edges (no ghost vertices), their surface at 0 and 15 m as ours
            B = o["Box2D"]
            skin = B.b2_polygonRadius
            x0, y0 = p_ll[0] - skin, p_ll[1] - skin
            x1, y1 = p_hr[0] + skin, p_hr[1] + skin
            v = [(x1, y0), (x1, y1), (x0, y1), (x0, y0)]
            fixtures = [B.b2FixtureDef(shape=B.b2EdgeShape(vertices=[v[i], v[(i + 1) % 4]]),
                                       density=1, friction=0.5, restitution=0)
                        for i in range(4)]
            box = world.CreateStaticBody(position=pos, fixtures=fixtures)
            box.sleepingAllowed = False
            box.userData = gen_world.BodyData()
            box.userData.shape = "edges"

        gen_world.create_fixed_box = edges
    os.makedirs(args.out, exist_ok=True)
    result = {"timing": cmd_timing, "chaos": cmd_chaos, "copy": cmd_copy,
              "order": cmd_order}[args.cmd](o, args)
    tag = "_p%d" % args.perturb if getattr(args, "perturb", 0) else ""
    with open(os.path.join(args.out, "probe_%s%s.json" % (args.cmd, tag)), "w") as f:
        json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
