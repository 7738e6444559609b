//! Renders a [`PipelineResult`] as the sections of `report.md`, with their
//! tables (`tables/*.csv`), figures (`figures/*.svg`) and files, one module
//! per group of sections.

mod closed_loop;
mod data;
mod differences;
mod estimation;
mod fmt;
mod identification;
mod solvers;

use crate::report::document::Report;
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
