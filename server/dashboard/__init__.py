"""The inspection dashboard: HTML at `/` and `/ui/...`, served by the service itself."""

from server.dashboard.install import install_dashboard
from server.dashboard.routes import router

__all__ = ["install_dashboard", "router"]
