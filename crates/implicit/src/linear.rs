//! Sparse linear solvers (placeholder).
