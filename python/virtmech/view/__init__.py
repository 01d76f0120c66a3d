"""`virtmech view`: a live 3-D viewer in the browser (viser), the mouse as the hand.

    virtmech view omni-fig11               # live: the scenario's device and mechanism at 1 kHz
    virtmech view out/omni-fig11           # replay a folder written by `virtmech run`

Python::

    from virtmech.view import ViewServer
    v = ViewServer("omni-fig11", port=8080).start()   # http://127.0.0.1:8080
    v.state()            # handle and target poses, wrench and its parts, t, real-time factor
    v.set_target(p)      # the hand's target, as the gizmo sets it
    v.stop()

GET http://127.0.0.1:8081/state (the port + 1, `state_port`) answers `state()` as JSON.
Needs the [view] extra (viser) and the [sim] extra (MuJoCo). See docs/viewer.md.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["ViewServer", "serve"]


def __getattr__(name: str):
    if name == "ViewServer":
        from .server import ViewServer

        return ViewServer
    raise AttributeError(name)


def resolve(source: str) -> str:
    """`source` if it names a log folder, a scenario file or a shipped scenario; else a
    UserError naming it."""
    from .. import scenarios as sc
    from ..errors import UserError

    p = Path(source)
    if p.is_dir() or p.is_file() or source in sc.names():
        return source
    if "/" in source or "\\" in source or p.suffix:
        raise UserError(
            f"LOG_DIR {source}: no such folder or scenario file; expected a folder written by "
            "`virtmech run` (log.csv and run.json) or a scenario .toml file"
        )
    raise UserError(
        f"SCENARIO {source}: no shipped scenario of that name; expected one of "
        f"{', '.join(sc.names())} (`virtmech scenarios`), a .toml file or a folder written "
        "by `virtmech run`"
    )


def serve(
    source: str,
    port: int = 8080,
    host: str = "127.0.0.1",
    state_port: int | None = None,
    open_browser: bool = False,
    record_dir: str = "out/view",
    seed: int | None = None,
    fps: float = 30.0,
) -> int:
    """Serves the viewer until Ctrl-C (or SIGTERM); returns 0. Mistakes in the input raise
    virtmech.errors.UserError before anything is served."""
    import signal
    import sys
    import threading

    from ..errors import UserError
    from .server import ViewServer, check_port

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    handlers = {}
    if threading.current_thread() is threading.main_thread():
        # Ctrl-C (also where the shell started us ignoring it) and SIGTERM end the viewer,
        # from the start on
        for sig in (signal.SIGINT, signal.SIGTERM):
            handlers[sig] = signal.signal(sig, interrupt)
    viewer = None
    try:
        source = resolve(source)
        state = port + 1 if state_port is None else state_port
        if state == port:
            raise UserError(f"--state-port {state}: the same as --port; expected another port")
        check_port(host, port)  # before anything is built
        check_port(
            host,
            state,
            f"--state-port {state}"
            if state_port is not None
            else f"--port {port} (the state endpoint listens on --port + 1 = {state})",
        )
        viewer = ViewServer(
            source,
            port=port,
            host=host,
            state_port=state_port,
            fps=fps,
            record_dir=record_dir,
            seed=seed,
        )
        viewer.start()
        print(
            f"virtmech view: {viewer.name} ({viewer.mode}) at {viewer.url} "
            f"(state: {viewer.state_url}); Ctrl-C to stop",
            flush=True,
        )
        if open_browser:
            import webbrowser

            webbrowser.open(viewer.url)
        viewer.wait()
    except KeyboardInterrupt:
        pass
    finally:
        try:
            if viewer is not None:
                viewer.stop()
        except KeyboardInterrupt:  # a second Ctrl-C while stopping
            pass
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    print("virtmech view: stopped", file=sys.stderr, flush=True)
    return 0
