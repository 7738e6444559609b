//! Renders a [`PipelineResult`] as the sections of `report.md`, with their
//! tables (`tables/*.csv`), figures (`figures/*.svg`) and files, one module
//! per group of sections.

mod closed_loop;
mod data;
mod differences;
mod estimation;
mod identification;
mod solvers;

use super::Report;
use crate::report::table::fmt_sig;
use kestrel_tricopter::pipeline::PipelineResult;
use std::path::Path;

/// Every section in order.
pub fn all(r: &mut Report, res: &PipelineResult, flights: Option<&Path>) -> anyhow::Result<()> {
    data::experiments(r, res, flights)?;
    data::sensor(r, res)?;
    identification::section(r, res)?;
    estimation::kalman(r, res)?;
    estimation::problems(r, res)?;
    solvers::explicit(r, res)?;
    solvers::fast_gradient(r, res)?;
    solvers::table_7_2(r, res)?;
    closed_loop::section(r, res)?;
    closed_loop::firmware(r, res)?;
    differences::section(r, res)
}

fn f3(v: f64) -> String {
    fmt_sig(v, 3)
}

fn f4(v: f64) -> String {
    fmt_sig(v, 4)
}

/// `a / b / c` with 3 significant digits.
fn j3(v: &[f64]) -> String {
    v.iter().map(|x| f3(*x)).collect::<Vec<_>>().join(" / ")
}

fn series_t(t: &[f64], v: impl Iterator<Item = f64>) -> Vec<(f64, f64)> {
    t.iter().copied().zip(v).collect()
}
