"""``sonarcal serve SESSION [--host 127.0.0.1] [--port 8080]``: the browser workbench."""

from __future__ import annotations

import contextlib
import io
import signal
import threading

from sonarcal_cli.ui import console


def add_parser(sub) -> None:
    p = sub.add_parser("serve", help="start the browser workbench on a session (prints the URL)")
    p.add_argument("session", help="session folder (holds session.yaml)")
    p.add_argument("--host", default="127.0.0.1",
                   help="interface to bind (default 127.0.0.1: this machine only; 0.0.0.0 exposes it to the network)")
    p.add_argument("--port", type=int, default=8080, help="TCP port (default 8080; 0 picks a free one)")
    p.add_argument("--allow-root", action="append", default=None, metavar="DIR",
                   help="folder the browser's path field may open sessions from (repeatable; default: the "
                        "session's parent folder and the current folder)")
    p.add_argument("--no-token", action="store_true",
                   help="do not require the secret token in the URL (only on a network you trust; the Origin "
                        "check stays)")
    p.set_defaults(run=run)


def run(args) -> int:
    from rich.markup import escape

    from calib_core.session import load_session

    load_session(args.session)  # a bad session fails here, as one line, before any server starts
    from app.server import Workbench

    with contextlib.redirect_stdout(io.StringIO()):  # viser's own banner shows the URL without the token
        wb = Workbench(args.session, host=args.host, port=args.port, allowed_roots=args.allow_root,
                       token=None if getattr(args, "no_token", False) else "auto")
    local = args.host in ("127.0.0.1", "localhost", "::1")
    if wb.port_warning:
        console.print(f"[yellow]{wb.port_warning}[/yellow]", markup=True, highlight=False)
    console.print(f"[bold]sonarcal workbench[/bold] on session {escape(wb.state.session.name)}")
    console.print(f"open [bold cyan]{wb.url}[/bold cyan] in a browser")
    if wb.token is None:
        console.print("[yellow]--no-token: any program that can reach this port can edit the session[/yellow]")
    if local:
        console.print("bound to 127.0.0.1: reachable from this machine only (use --host 0.0.0.0 to share it)")
    else:
        console.print(f"[yellow]bound to {args.host}: reachable from the network; anyone who can reach it can "
                      "edit this session[/yellow]")
    console.print("press Ctrl+C to stop")
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)}
    try:
        while not stop.wait(3600):
            pass
        console.print("stopping")
    finally:
        wb.stop()  # removes the uploads and the lock file
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0
