"""Fixtures of the experiment tests (helpers in ``_helpers``)."""

from tests.research.experiments._helpers import stand_in_data

__all__ = ["stand_in_data"]
