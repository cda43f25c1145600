"""The knowledge base in the loop: points out, type activation, MPF suggestions in."""

from planner.knowledge.client import KnowledgeClient
from planner.knowledge.matching import Activation
from planner.knowledge.session import KnowledgeSession
from planner.knowledge.stats import KnowledgeStats

__all__ = ["Activation", "KnowledgeClient", "KnowledgeSession", "KnowledgeStats"]
