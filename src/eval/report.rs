//! The `silva eval` report: one row per tree, written as JSON and as a table.
//!
//! Rows gather what each stage measured; a stage that did not run for a tree
//! leaves its columns empty (`null` in JSON, `-` in the table) rather than
//! inventing a value.

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use serde::Serialize;

/// Runs `f` `repeat` times (at least once) and returns the last result and the
/// median wall time. Medians, not means: the machines are small and noisy.
pub fn timed_median<T>(repeat: usize, mut f: impl FnMut() -> T) -> (T, Duration) {
    let mut times = Vec::with_capacity(repeat.max(1));
    let mut last = None;
    for _ in 0..repeat.max(1) {
        let start = Instant::now();
        last = Some(f());
        times.push(start.elapsed());
    }
    times.sort();
    (last.expect("ran at least once"), times[times.len() / 2])
}

/// A column of the readable table: header and how to print one row's cell.
pub struct Column<R> {
    /// Header text.
    pub header: &'static str,
    /// Cell text for a row; `None` prints as `-`.
    pub cell: fn(&R) -> Option<String>,
}

/// Renders rows as a fixed-width text table with right-aligned cells.
pub fn render_table<R>(rows: &[R], columns: &[Column<R>]) -> String {
    let cells: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            columns
                .iter()
                .map(|c| (c.cell)(r).unwrap_or_else(|| "-".into()))
                .collect()
        })
        .collect();
    let widths: Vec<usize> = columns
        .iter()
        .enumerate()
        .map(|(i, c)| {
            cells
                .iter()
                .map(|row| row[i].len())
                .chain([c.header.len()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let mut out = String::new();
    let line = |out: &mut String, texts: &mut dyn Iterator<Item = &str>| {
        let parts: Vec<String> = texts
            .zip(&widths)
            .map(|(t, w)| format!("{t:>w$}"))
            .collect();
        let _ = writeln!(out, "{}", parts.join("  ").trim_end());
    };
    line(&mut out, &mut columns.iter().map(|c| c.header));
    for row in &cells {
        line(&mut out, &mut row.iter().map(String::as_str));
    }
    out
}

/// Median of a list of numbers (`None` when empty).
pub fn median(values: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    })
}

/// Where a row's cloud came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// A file from a `--data` folder (no ground truth).
    Data,
    /// A synthetic tree with known skeleton.
    Synthetic,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_even_and_odd() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[]), None);
    }

    #[test]
    fn table_aligns_and_marks_missing() {
        struct R(u32, Option<f32>);
        let cols = [
            Column::<R> {
                header: "n",
                cell: |r| Some(r.0.to_string()),
            },
            Column::<R> {
                header: "value",
                cell: |r| r.1.map(|v| format!("{v:.1}")),
            },
        ];
        let t = render_table(&[R(1, Some(2.5)), R(100, None)], &cols);
        assert_eq!(t, "  n  value\n  1    2.5\n100      -\n");
    }
}
