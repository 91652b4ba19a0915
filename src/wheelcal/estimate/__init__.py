"""Estimators: the joint ML fit at the Cramér–Rao bound, the paper's four steps, and tools."""
