//! How every number the results and the reports show is written: the one set of
//! formatters `results.rs` and `report.rs` share (in `report.rs` until 2026-11-27, which
//! `results.rs` then imported from; `report` re-exports them).

/// A time in seconds, 3 decimals.
pub fn fmt_s(x: f64) -> String {
    format!("{x:.3}")
}

/// A time in milliseconds, 3 decimals.
pub fn fmt_ms(x: f64) -> String {
    format!("{x:.3}")
}

/// A rate or plain number, 2 decimals.
pub fn fmt_2(x: f64) -> String {
    format!("{x:.2}")
}

/// A share as a percentage with 2 decimals (`0.9905` -> `99.05%`).
pub fn fmt_pct(x: f64) -> String {
    format!("{:.2}%", x * 100.0)
}

/// An error or correlation value, 6 significant decimals.
pub fn fmt_err(x: f64) -> String {
    format!("{x:.6}")
}

/// A per-channel bias as signed percentages, `-7.10% / -8.02% / -9.20%`.
pub fn fmt_bias(b: [f64; 3]) -> String {
    b.map(|c| format!("{:+.2}%", c * 100.0)).join(" / ")
}
