"""``sonarcal serve SESSION [--host 127.0.0.1] [--port 8080]``: the browser workbench."""

from __future__ import annotations

import time

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
    p.set_defaults(run=run)


def run(args) -> int:
    from calib_core.session import load_session

    load_session(args.session)  # a bad session fails here, as one line, before any server starts
    from app.server import Workbench

    wb = Workbench(args.session, host=args.host, port=args.port, allowed_roots=args.allow_root)
    local = args.host in ("127.0.0.1", "localhost", "::1")
    console.print(f"[bold]sonarcal workbench[/bold] on session {wb.state.session.name}")
    console.print(f"open [bold cyan]{wb.url}[/bold cyan] in a browser")
    if local:
        console.print("bound to 127.0.0.1: reachable from this machine only (use --host 0.0.0.0 to share it)")
    else:
        console.print(f"[yellow]bound to {args.host}: reachable from the network; anyone who can reach it can "
                      "edit this session[/yellow]")
    console.print("press Ctrl+C to stop")
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        console.print("stopping")
    finally:
        wb.stop()
    return 0
