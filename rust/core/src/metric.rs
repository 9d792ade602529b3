//! The strand metric.
