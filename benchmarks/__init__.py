"""Benchmarks of csws: accuracy against constructed ground truth, and speed."""
