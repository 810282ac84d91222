"""``calbench serve [--sim] [--sim-speed N] [--host H] [--port P] [--agent MODE]``: the REST
service and dashboard.

The service never drives the bench itself: by default it starts the bench's agent
(``calbench agent``, :mod:`api.agent.supervisor`) as a child process and keeps it running;
``--agent external`` leaves that to someone else (docker compose, systemd), ``--agent
embedded`` runs the agent in a thread of the service (one process, as before).

Settings come from ``CALBENCH_*`` (see ``docs/service.md``). Without ``CALBENCH_TOKENS``
an admin token is generated and printed once on stderr (it may also create database tokens
at ``/api/tokens``), so there is never an unauthenticated write endpoint; with ``--sim``
and no tokens, reads are also opened (``CALBENCH_PUBLIC_READ`` set explicitly wins) so the
dashboard of a development bench opens without a token.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from api.auth import new_secret, parse_tokens
from api.cli import BadInput
from api.drift import parse_time_of_day
from api.settings import Settings
from api.startup_check import check_configuration


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``calbench serve``."""
    parser.add_argument("--sim", action="store_true", help="drive a simulated bench (real drivers, loopback)")
    parser.add_argument(
        "--sim-speed", type=float, default=None, metavar="N", help="simulated seconds per wall second"
    )
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    parser.add_argument("--log-level", default="info", choices=["debug", "info", "warning", "error"])
    parser.add_argument(
        "--bench-file",
        default=None,
        metavar="PATH",
        help="the bench's configuration file (calbench-bench/1; default CALBENCH_BENCH_FILE, "
        "else the simulated bench's)",
    )
    parser.add_argument(
        "--agent",
        default="spawn",
        choices=["spawn", "external", "embedded"],
        help="spawn (default): start and watch the bench agent process; external: it runs elsewhere; "
        "embedded: in a thread of this process",
    )


def serve_settings(args: argparse.Namespace) -> tuple[Settings, dict[str, str]]:
    """Settings from the environment and the flags, and any generated token ``{secret: role}``.

    :raises BadInput: bad tokens, drift time, port or speed, or a configuration
        :func:`~api.startup_check.check_configuration` refuses (device URL, database file).
    """
    try:
        settings = Settings()
        parse_tokens(settings.tokens)
        parse_time_of_day(settings.drift_time)
    except ValueError as exc:
        raise BadInput(str(exc).splitlines()[0]) from None
    if not 0 < args.port < 65536:
        raise BadInput(f"--port {args.port}: expected 1..65535")
    update: dict[str, object] = {}
    if args.sim:
        update["sim"] = True
    if args.sim_speed is not None:
        if not args.sim_speed > 0:
            raise BadInput(f"--sim-speed {args.sim_speed}: expected a positive number")
        update["sim_speed"] = args.sim_speed
    from api.agent.session import bench_config_for

    if getattr(args, "bench_file", None) is not None:
        update["bench_file"] = Path(args.bench_file)
    update["agent"] = "embedded" if getattr(args, "agent", "spawn") == "embedded" else "external"
    generated: dict[str, str] = {}
    if not settings.tokens:
        generated[new_secret()] = "admin"
        if settings.sim or args.sim:
            explicit = os.environ.get("CALBENCH_PUBLIC_READ") is not None
            update["public_read"] = settings.public_read if explicit else True
    final = settings.model_copy(update=update)
    try:  # device URLs and database file first, then the bench file (naming the file and the key)
        check_configuration(final)
        bench_config_for(final, bool(args.sim or settings.sim))
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    return final, generated


def run(args: argparse.Namespace) -> int:
    """Execute ``calbench serve``."""
    import uvicorn

    from api.main import create_app

    settings, generated = serve_settings(args)
    for secret, role in generated.items():
        print(f"calbench serve: no CALBENCH_TOKENS; {role} token of this process: {secret}", file=sys.stderr)
    if settings.public_read:
        print("calbench serve: reads need no token (public_read)", file=sys.stderr)
    print(
        f"calbench serve: bench {settings.bench_name!r}, database {settings.effective_database_url}, "
        f"{'simulated bench' if settings.sim else settings.table_url}, http://{args.host}:{args.port}/",
        file=sys.stderr,
    )
    supervisor = None
    if args.agent == "spawn":
        from api.agent.supervisor import AgentSupervisor

        supervisor = AgentSupervisor(settings, sim=settings.sim, sim_speed=args.sim_speed)
        supervisor.start()
    try:
        stop_agent = supervisor.stop if supervisor is not None else None
        app = create_app(settings, extra_tokens=generated, on_shutdown=stop_agent)
        uvicorn.run(app, host=args.host, port=args.port, log_level=args.log_level)
    finally:  # also when the app never started; stopping twice is harmless
        if supervisor is not None:
            supervisor.stop()
    return 0
