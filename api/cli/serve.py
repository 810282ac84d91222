"""``calbench serve [--sim] [--sim-speed N] [--host H] [--port P] [--agent MODE] [--workers N]``:
the REST service and dashboard.

The service never drives the bench itself: by default it starts the bench's agent
(``calbench agent``, :mod:`station.agent.supervisor`) as a child process and keeps it running;
``--agent external`` leaves that to someone else (docker compose, systemd), ``--agent
embedded`` runs the agent in a thread of the service (one process, as before).

``--workers N`` serves the API from N processes (uvicorn's workers, each building the app with
:func:`worker_app` from the settings this process resolved, handed down in
:data:`SERVE_CONFIG_ENV`); they share nothing but the database, so any of them answers any
request and streams any run. The bench agent is then never embedded in a worker.

Settings come from ``CALBENCH_*`` (see ``docs/service.md``). Without ``CALBENCH_TOKENS``
the first start creates an admin token in the database (stored hashed) and prints it once on
stderr; later starts keep it (:mod:`api.first_admin`). It may create the lab's named tokens at
``/api/tokens``, so there is never an unauthenticated write endpoint; with ``--sim``
and no tokens, reads are also opened (``CALBENCH_PUBLIC_READ`` set explicitly wins) so the
dashboard of a development bench opens without a token.

A client gets :data:`api.slow_clients.HEADER_READ_TIMEOUT_S` to send a request's headers
(:mod:`api.slow_clients`); a stalled body is cut by :mod:`api.guard`.
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import socket
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from pydantic import ValidationError

from api.auth import new_secret, parse_tokens
from api.cli import BadInput
from api.slow_clients import PROTOCOL
from api.startup_check import check_configuration
from station.drift import parse_time_of_day
from station.settings import Settings

if TYPE_CHECKING:
    from fastapi import FastAPI

SERVE_CONFIG_ENV = "CALBENCH_SERVE_CONFIG"
"""Environment variable through which ``calbench serve --workers N`` hands its resolved settings
and generated tokens to the worker processes (JSON ``{"settings": {...}, "extra_tokens": {...}}``)."""
MAX_WORKERS = 64


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
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        metavar="N",
        help="API worker processes sharing the port (default 1); they share only the database",
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
    except ValidationError as exc:  # one line: the first field at fault and why
        first = exc.errors()[0]
        msg = str(first["msg"]).removeprefix("Value error, ")
        name = "CALBENCH_" + "_".join(str(p) for p in first["loc"][:1]).upper()
        raise BadInput(msg if name in msg else f"{name}: {msg}") from None
    except ValueError as exc:
        raise BadInput(str(exc).splitlines()[0]) from None
    if not 0 < args.port < 65536:
        raise BadInput(f"--port {args.port}: expected 1..65535")
    workers = getattr(args, "workers", 1)
    if not 1 <= workers <= MAX_WORKERS:
        raise BadInput(f"--workers {workers}: expected 1..{MAX_WORKERS}")
    if workers > 1 and getattr(args, "agent", "spawn") == "embedded":
        raise BadInput(
            f"--workers {workers} with --agent embedded: each worker would drive the bench; "
            "use --agent spawn (default) or external"
        )
    update: dict[str, object] = {}
    if args.sim:
        update["sim"] = True
    if args.sim_speed is not None:
        if not args.sim_speed > 0:
            raise BadInput(f"--sim-speed {args.sim_speed}: expected a positive number")
        update["sim_speed"] = args.sim_speed
    from station.execution.devices import bench_config_for, check_sim_link

    if getattr(args, "bench_file", None) is not None:
        update["bench_file"] = Path(args.bench_file)
    update["agent"] = "embedded" if getattr(args, "agent", "spawn") == "embedded" else "external"
    if not settings.link_key:  # one key for all the workers of this service
        update["link_key"] = new_secret()
    generated: dict[str, str] = {}  # tokens handed to the app besides the configured ones: none
    if not settings.tokens and (settings.sim or args.sim):  # the admin token: api.first_admin, at start
        explicit = os.environ.get("CALBENCH_PUBLIC_READ") is not None
        update["public_read"] = settings.public_read if explicit else True
    final = settings.model_copy(update=update)
    try:  # device URLs and database file first, then the bench file (naming the file and the key)
        check_configuration(final)
        bench_config_for(final, bool(args.sim or settings.sim))
        if final.sim:
            check_sim_link(final.sim_speed, final.sim_sample_rate_hz)
    except ValueError as exc:
        raise BadInput(str(exc)) from None
    return final, generated


def worker_app() -> FastAPI:
    """The app of one ``calbench serve --workers N`` worker (uvicorn calls this factory in each
    worker process): the settings and generated tokens of :data:`SERVE_CONFIG_ENV`.

    :raises RuntimeError: the variable is missing or malformed (the worker was not started by
        ``calbench serve``).
    """
    from api.main import create_app

    raw = os.environ.get(SERVE_CONFIG_ENV)
    try:
        config = json.loads(raw or "")
        settings = Settings.model_validate(config["settings"])
        extra_tokens = {str(k): str(v) for k, v in config["extra_tokens"].items()}
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise RuntimeError(
            f"{SERVE_CONFIG_ENV}: missing or malformed ({exc}); API workers are started by calbench serve"
        ) from None
    return create_app(settings, extra_tokens=extra_tokens)


def listen_socket(host: str, port: int) -> socket.socket:
    """The service's listening socket, bound before anything else starts.

    :raises BadInput: the address cannot be bound (in use: another service), one line.
    """
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except OSError as exc:
        raise BadInput(f"--host {host}: {exc.strerror or exc}") from None
    family, _type, _proto, _name, address = infos[0]
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(address)
    except OSError as exc:
        sock.close()
        why = "address already in use (another calbench serve?)" if exc.errno == errno.EADDRINUSE else exc
        raise BadInput(f"cannot listen on {host}:{port}: {why}") from None
    sock.set_inheritable(True)
    return sock


def run(args: argparse.Namespace) -> int:
    """Execute ``calbench serve``.

    The port is bound first: a service that cannot listen exits at once (code 2, one line)
    before it starts or touches any agent. With ``--agent embedded`` this process drives the
    table and holds the bench's lock (:mod:`station.execution.bench_lock`); a bench already driven is
    refused (code 3, one line naming the holder)."""
    import uvicorn

    from api.first_admin import announcement, first_admin
    from api.main import create_app
    from station.execution.bench_lock import HELD_EXIT, BenchHeld, BenchLock

    settings, generated = serve_settings(args)
    sock = listen_socket(args.host, args.port)
    lock = None
    if args.agent == "embedded":
        lock = BenchLock(settings, "calbench serve")
        try:
            lock.acquire()
        except BenchHeld as exc:
            sock.close()
            print(f"calbench serve: {exc}", file=sys.stderr)
            return HELD_EXIT
    if not settings.tokens:
        try:
            print(announcement(first_admin(settings.effective_database_url)), file=sys.stderr)
        except Exception as exc:  # the database cannot be opened: say so on one line
            sock.close()
            if lock is not None:
                lock.release()
            raise BadInput(
                f"the admin token could not be read or stored: {type(exc).__name__}: {exc}"
            ) from None
    if settings.public_read:
        print("calbench serve: reads need no token (public_read)", file=sys.stderr)
    workers = getattr(args, "workers", 1)
    print(
        f"calbench serve: bench {settings.bench_name!r}, database {settings.effective_database_url}, "
        f"{'simulated bench' if settings.sim else settings.table_url}, http://{args.host}:{args.port}/"
        + (f", {workers} API workers" if workers > 1 else ""),
        file=sys.stderr,
    )
    supervisor = None
    if args.agent == "spawn":
        from station.agent.supervisor import AgentSupervisor

        supervisor = AgentSupervisor(settings, sim=settings.sim, sim_speed=args.sim_speed)
        supervisor.start()
    try:
        if workers > 1:
            sock.close()  # uvicorn's worker manager binds its own
            config = {"settings": settings.model_dump(mode="json"), "extra_tokens": generated}
            os.environ[SERVE_CONFIG_ENV] = json.dumps(config)
            uvicorn.run(
                "api.cli.serve:worker_app",
                factory=True,
                workers=workers,
                host=args.host,
                port=args.port,
                log_level=args.log_level,
                http=PROTOCOL,
            )
        else:
            stop_agent = supervisor.stop if supervisor is not None else None
            app = create_app(settings, extra_tokens=generated, on_shutdown=stop_agent)
            server_config = uvicorn.Config(
                app, host=args.host, port=args.port, log_level=args.log_level, http=PROTOCOL
            )
            uvicorn.Server(server_config).run(sockets=[sock])
    finally:  # also when the app never started; stopping twice is harmless
        if supervisor is not None:
            supervisor.stop()
        sock.close()
        if lock is not None:
            lock.release()
    return 0
