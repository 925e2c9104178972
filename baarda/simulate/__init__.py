"""Synthetic blocks with known truth: aerial photo blocks, independent-model blocks and
on-line strips.
"""
