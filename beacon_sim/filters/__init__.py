"""Bayesian filters on top of the core: the interface, the built-in filters, loading.

Filters never import pygame and never see the true pose.
"""
