"""Per-type GP surrogates in the service: the engine (cache, fit worker, pending suggestions)
and the suggest/predict services. `install(app)` wires the engine into the app's hooks."""

from __future__ import annotations

from fastapi import FastAPI


def install(app: FastAPI) -> None:
    """Create the engine from the app's settings and plug it into the service hooks:
    new points queue fits, type detail shows the surrogate state, the lifespan starts and
    stops the fit worker; `app.state.predict(kb, type_id, xs)` serves in-process callers and
    `app.state.predict_with_uncertainty` (same arguments) also tells the dashboard where the
    model is unsure."""
    from server.surrogates.engine import SurrogateEngine

    settings = app.state.settings
    config = settings.surrogate
    app.state.surrogates = None
    if not config.enabled:
        return
    pending_store = config.pending_store
    if pending_store == "auto":
        pending_store = "database" if app.state.store.dialect == "postgresql" else "memory"
    engine = SurrogateEngine(
        app.state.store,
        config,
        pending_in_database=pending_store == "database",
        replica=settings.replica_name,
    )
    hooks = app.state.hooks
    hooks.points_added.append(engine.notify)
    hooks.kb_deleted.append(engine.forget)
    hooks.surrogate_state = engine.state
    hooks.on_startup.append(engine.start)
    hooks.on_shutdown.append(engine.stop)
    app.state.surrogates = engine
    app.state.predict = engine.predict
    app.state.predict_with_uncertainty = engine.predict_with_uncertainty
