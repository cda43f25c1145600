"""The knowledge base in the loop: points out, type activation, MPF suggestions in."""

from planner.knowledge.session import Activation, KnowledgeClient, KnowledgeSession

__all__ = ["Activation", "KnowledgeClient", "KnowledgeSession"]
