"""Identify a fleet on Dask: a Parquet data set partitioned by machine and day, the moment
statistics of every partition computed on the workers, merged per machine, every machine
identified, and the machines that left their fleet named (docs/distributed.md,
docs/fleet.md).

    python python/examples/fleet_dask.py --out /tmp/fleet --workers 2

The fleet is synthetic: 200 one-mass axes ``m x'' + fv v + fc sign(v) + k x = u``
(m = 1 kg known), every parameter scattered 3 % from part to part around the nominal,
five with a fault (Coulomb friction doubled on three, 30 % of the stiffness lost on two).
Each machine logs one record a day for three days (60 s at 100 Hz at the day's excitation
level, 1 % noise on every channel), stored as
``OUT/data/machine=m017/day=2/part.parquet``.

Why Dask: the moment computation is a plain Python function of one partition's file, so
``Client.map`` over the partitions and ``Client.submit`` of the merges are the whole
program; a ``LocalCluster`` runs it on one machine (and in the tests), a cluster's
scheduler address runs it on many (``--scheduler tcp://host:8786``), unchanged. Workers
read the Parquet files themselves (dynid reads Parquet), so only the statistics travel:
a few hundred kilobytes per partition (docs/distributed.md).
"""

import argparse
import json
import pathlib
import time

import numpy as np

import dynid

#: The axis, with its parameters' nominal values.
SOURCE = """model axis {
    body m = 1.0
    input u on m
    spring k (ground, m) ~ 4.0
    damper fv (ground, m) ~ 0.4
    force friction (ground, m) = fc ~ 0.3 * sign(v)
    excite u: lowpass(corner = 10) levels [6, 15, 40]
}"""

NOMINAL = {"k": 4.0, "fv": 0.4, "fc": 0.3}
SCATTER = 0.03
#: The faulty machines: what moved and by which factor.
FAULTS = {17: ("fc", 2.0), 58: ("k", 0.7), 101: ("fc", 2.0), 150: ("k", 0.7), 189: ("fc", 2.0)}
DAYS = 3
DURATION = 60.0
SAMPLE = 0.01


def machine_name(i: int) -> str:
    return f"m{i:03d}"


def machine_parameters(i: int, seed: int = 1):
    """Machine ``i``'s true parameters: the nominal scattered, then its fault."""
    rng = np.random.default_rng([seed, i])
    p = {k: v * (1.0 + SCATTER * rng.standard_normal()) for k, v in NOMINAL.items()}
    if i in FAULTS:
        name, factor = FAULTS[i]
        p[name] *= factor
    return p


def write_fleet(root: pathlib.Path, machines: int = 200, seed: int = 1):
    """Simulate every machine and write its days as Parquet partitions; the paths, by
    machine."""
    model = dynid.Model.from_source(SOURCE, "axis")
    paths = {}
    for i in range(machines):
        name = machine_name(i)
        levels = model.simulate(duration=DURATION, seed=seed * 100_000 + i, sample=SAMPLE, noise=0.01, burn_in=20.0, parameters=machine_parameters(i, seed))
        paths[name] = []
        for day, level in enumerate(levels, start=1):
            path = root / f"machine={name}" / f"day={day}" / "part.parquet"
            path.parent.mkdir(parents=True, exist_ok=True)
            level.to_parquet(path, index=False)
            paths[name].append(str(path))
    return paths


def partitions(root: pathlib.Path):
    """The data set's partitions, by machine (from the ``machine=``/``day=`` folders)."""
    out = {}
    for path in sorted(root.glob("machine=*/day=*/*.parquet")):
        machine = path.parent.parent.name.split("=", 1)[1]
        out.setdefault(machine, []).append(str(path))
    return out


def piece(path: str, design: str, model: dynid.Model):
    """One partition's moment statistics (runs on a worker)."""
    return dynid.moments(model, [path], design)


def identify_machine(stats, model: dynid.Model):
    """A machine's merged statistics solved: its identification document."""
    return model.identify_moments(stats).to_dict()


def identify_fleet(client, by_machine, design: str, model: dynid.Model):
    """Map the moment computation over every partition, merge per machine, identify every
    machine; the identification documents by machine. Run as a script, so that Dask ships
    these functions to the workers by value."""
    docs = {}
    for machine, paths in by_machine.items():
        parts = client.map(piece, paths, design=design, model=model, pure=False)
        merged = client.submit(dynid.merge, parts, pure=False)
        docs[machine] = client.submit(identify_machine, merged, model, pure=False)
    return dict(zip(docs, client.gather(list(docs.values()))))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="folder for the data set and the results")
    ap.add_argument("--machines", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2, help="local worker processes (without --scheduler)")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler instead of a LocalCluster")
    args = ap.parse_args(argv)

    from dask.distributed import Client, LocalCluster

    root = pathlib.Path(args.out) / "data"
    if not root.exists():
        t = time.perf_counter()
        write_fleet(root, args.machines)
        print(f"simulated {args.machines} machines × {DAYS} days in {time.perf_counter() - t:.1f} s → {root}")
    by_machine = partitions(root)
    model = dynid.Model.from_source(SOURCE, "axis")
    # The design is fixed before the map, from a sample: the first machine's days.
    design = dynid.moment_design(model, next(iter(by_machine.values())))

    cluster = None
    if args.scheduler:
        client = Client(args.scheduler)
    else:
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        t = time.perf_counter()
        docs = identify_fleet(client, by_machine, design, model)
        print(f"identified {len(docs)} machines from {sum(map(len, by_machine.values()))} partitions in {time.perf_counter() - t:.1f} s")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    view = dynid.fleet(docs)
    print(view)
    # The machines' identification documents and the fleet's view, for scripts and tests.
    out = pathlib.Path(args.out)
    (out / "identifications.json").write_text(json.dumps(docs))
    (out / "fleet.json").write_text(json.dumps(view.to_dict()))
    return view


if __name__ == "__main__":
    main()
