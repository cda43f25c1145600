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
    from server.surrogates.engine import EngineConfig, SurrogateEngine
    from surrogate.optimize import OptimizerConfig

    settings = app.state.settings
    app.state.surrogates = None
    if not settings.surrogate_enabled:
        return
    pending_store = settings.surrogate_pending_store
    if pending_store == "auto":
        pending_store = "database" if app.state.store.dialect == "postgresql" else "memory"
    config = EngineConfig(
        fit_in_child_process=settings.surrogate_fit_process,
        max_inducing=settings.surrogate_max_inducing,
        max_fit_points=settings.surrogate_max_fit_points,
        instant_fit_points=settings.surrogate_instant_fit_points,
        instant_fit_iters=settings.surrogate_instant_fit_iters,
        instant_refit_factor=settings.surrogate_instant_refit_factor,
        additive=settings.surrogate_additive,
        balance_classes=settings.surrogate_balance_classes,
        refresh_s=settings.surrogate_refresh_s,
        pending_ttl_s=settings.surrogate_pending_ttl_s,
        prefit_types=settings.surrogate_prefit_types,
        optimizer=OptimizerConfig(
            pop_size=settings.surrogate_pop_size,
            n_gen=settings.surrogate_generations,
            raw_samples=settings.surrogate_raw_samples,
            margin=settings.surrogate_mpf_margin,
            margin_abs=settings.surrogate_mpf_margin_abs,
        ),
        share_fits=settings.surrogate_share_fits,
        pending_in_database=pending_store == "database",
        claim_retry_s=settings.surrogate_claim_retry_s,
        **({"replica": settings.replica_name} if settings.replica_name else {}),
    )
    engine = SurrogateEngine(app.state.store, config)
    hooks = app.state.hooks
    hooks.points_added.append(engine.notify)
    hooks.kb_deleted.append(engine.forget)
    hooks.surrogate_state = engine.state
    hooks.on_startup.append(engine.start)
    hooks.on_shutdown.append(engine.stop)
    app.state.surrogates = engine
    app.state.predict = engine.predict
    app.state.predict_with_uncertainty = engine.predict_with_uncertainty
