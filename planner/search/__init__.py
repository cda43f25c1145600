"""PW-UCT binding search over a `BindingWorld`, independent of any simulator."""

from planner.search.pwuct import PWUCT, SearchObserver, SearchProgress, SearchResult

__all__ = ["PWUCT", "SearchObserver", "SearchProgress", "SearchResult"]
