"""The `sp` command's arguments: one subcommand each for plan, check, run, serve, emulate and
audit (DESIGN.md section 8 fixes plan, check and run).  Declarative, hence one long function.
"""

from __future__ import annotations

import argparse


def parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sp", description="Sequence Planner")
    commands = parser.add_subparsers(dest="command", required=True)
    plan = commands.add_parser("plan", help="find a minimal safe plan to a goal")
    plan.add_argument("model", help="model file (YAML)")
    plan.add_argument("--goal", required=True, help="goal expression, e.g. 'r1.pos == bp1'")
    plan.add_argument("--state", help="start state: JSON object name -> value (all variables)")
    plan.add_argument("--max-steps", type=_non_negative, default=100, metavar="N")
    plan.add_argument("--maintenance", action="store_true", help="allow maintenance transitions")
    plan.add_argument(
        "--restart", action="store_true", help="restart mode: allow restart abilities"
    )
    plan.add_argument("--json", action="store_true", help="print one JSON object")
    plan.add_argument(
        "--engine",
        choices=("bdd", "sat"),
        default="bdd",
        help="bdd: symbolic breadth-first search (default); sat: incremental SAT BMC",
    )
    run = commands.add_parser(
        "run", help="run the station headless against its simulated world; print the event log"
    )
    run.add_argument("model", help="model file (YAML)")
    run.add_argument("--scenario", help="scenario file (YAML): start, faults, operator answers")
    run.add_argument(
        "--speed",
        type=float,
        default=None,
        metavar="X",
        help="X times real time (default 1); 0 runs as fast as possible; not with --devices "
        "(emulated devices run in real time)",
    )
    run.add_argument(
        "--devices",
        metavar="FILE",
        help="play on emulated devices (started from this device file) in real time, "
        "through ur_rtde and Modbus TCP",
    )
    run.add_argument(
        "--running-emulators",
        action="store_true",
        help="with --devices: use the emulators already serving the device file (sp emulate) "
        "instead of starting them; the run puts them back to its start first",
    )
    run.add_argument("--json", action="store_true", help="print events as JSON lines")
    run.add_argument(
        "--sequential",
        action="store_true",
        help="one operation at a time instead of the operation plan's partial order (for "
        "comparison; a scenario's config can say the same)",
    )
    run.add_argument(
        "--quiet",
        action="store_true",
        help="leave out effects and taken transitions (the routine part of the log)",
    )
    check = commands.add_parser("check", help="validate a model and print its size")
    check.add_argument("model", help="model file (YAML)")
    check.add_argument("--json", action="store_true", help="print one JSON object")
    check.add_argument(
        "--reachable",
        action="store_true",
        help="also count the states plans can reach from the initial state (explores them all)",
    )
    for command in (plan, run, check):
        command.add_argument(
            "--no-cache",
            action="store_true",
            help="read the model and synthesise its supervisor anew instead of reusing what "
            "was saved for this model text (in $SP_CACHE_DIR or ~/.cache/sequence-planner)",
        )
    serve = commands.add_parser(
        "serve", help="run the station: runner, simulated devices, web HMI and store"
    )
    serve.add_argument("--model", default="models/demo_station.yaml", help="model file (YAML)")
    serve.add_argument("--db", default="sqlite:///station.db", help="database URL")
    serve.add_argument(
        "--keys",
        help="the station's key file, kept outside the database (default: beside a SQLite "
        "file, or $SP_KEY_FILE); made at the first start",
    )
    serve.add_argument(
        "--trusted-proxy",
        action="append",
        default=[],
        metavar="ADDRESS",
        help="a reverse proxy (address or network) whose X-Forwarded-For is believed; "
        "none by default",
    )
    serve.add_argument(
        "--api-docs",
        action="store_true",
        help="serve the API's documentation at /docs (a vendored Swagger UI) and its schema "
        "at /openapi.json; off by default",
    )
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=8000)
    serve.add_argument("--period", type=float, default=0.1, help="runner tick period, seconds")
    serve.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="simulated time runs X times faster than real time (demos and tests)",
    )
    serve.add_argument(
        "--secure-cookies", action="store_true", help="session cookies over HTTPS only"
    )
    serve.add_argument("--no-cache", action="store_true", help="do not reuse saved supervisors")
    serve.add_argument(
        "--model-seconds",
        type=float,
        default=60.0,
        metavar="S",
        help="a model version's supervisor must be built within S seconds to be activated",
    )
    serve.add_argument(
        "--model-memory",
        type=int,
        default=2048,
        metavar="MB",
        help="memory a model may take to be read or built (in a child process)",
    )
    serve.add_argument(
        "--sequential",
        action="store_true",
        help="one operation at a time instead of the operation plan's partial order",
    )
    serve.add_argument(
        "--devices",
        metavar="FILE",
        help="run on the devices of this device file (ur_rtde, Modbus TCP) instead of the "
        "simulated world",
    )
    serve.add_argument(
        "--emulate",
        action="store_true",
        help="with --devices: start the file's emulators first (the demo), and let the "
        "simulation panel's faults act on them",
    )
    emulate = commands.add_parser(
        "emulate",
        help="start the emulators of a device file (UR controllers, Modbus devices) and keep "
        "them running until Ctrl-C",
    )
    emulate.add_argument("devices", help="device file (YAML)")
    emulate.add_argument(
        "--model",
        default="models/demo_station.yaml",
        help="the station model the device file is checked against (its start values too)",
    )
    audit = commands.add_parser("audit", help="check the audit log")
    audit_commands = audit.add_subparsers(dest="audit_command", required=True)
    verify = audit_commands.add_parser(
        "verify",
        help="check the audit log (chain, seals, checkpoints) and the users; exit 1 if not intact",
    )
    verify.add_argument("--db", default="sqlite:///station.db", help="database URL")
    verify.add_argument(
        "--keys", help="the station's key file (default: beside a SQLite file, or $SP_KEY_FILE)"
    )
    store = commands.add_parser("store", help="look after the station's store")
    store_commands = store.add_subparsers(dest="store_command", required=True)
    accept = store_commands.add_parser(
        "accept",
        help="seal again, as they are, the rows `sp audit verify` found changed outside the "
        "station (after a restore from a backup, or a repair), so that it starts; audited",
    )
    accept.add_argument("--db", default="sqlite:///station.db", help="database URL")
    accept.add_argument(
        "--keys", help="the station's key file (default: beside a SQLite file, or $SP_KEY_FILE)"
    )
    accept.add_argument("--station", help="the station's name (default: the store's only one)")
    accept.add_argument("--by", required=True, help="who checked the rows and accepts them")
    accept.add_argument("--why", required=True, help="why they may be trusted, for the audit")
    return parser


def _non_negative(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if value < 0:
        raise argparse.ArgumentTypeError("must be 0 or more")
    return value
