//! `strata stress`: the stiff and extreme suite (see `strata_reports::stress`), one
//! table row per case, every engine against the f64 oracle.

use crate::common::{note, print_out};
use std::time::Instant;
use strata_reports::stress::{cases, format_table, Budget, Runner};

/// Arguments of `strata stress`.
#[derive(clap::Args)]
pub struct Args {
    /// The test suite's smaller budget (a few seconds).
    #[arg(long)]
    quick: bool,
    /// Run only the cases whose name contains this text.
    #[arg(long)]
    case: Option<String>,
}

pub fn run(args: Args) -> Result<(), String> {
    let budget = if args.quick {
        Budget::quick()
    } else {
        Budget::full()
    };
    let runner = Runner::new(budget);
    let selected: Vec<_> = cases()
        .into_iter()
        .filter(|c| args.case.as_deref().is_none_or(|s| c.name.contains(s)))
        .filter(|c| budget.includes(c))
        .collect();
    if selected.is_empty() {
        return Err(format!(
            "no case matches {:?}",
            args.case.unwrap_or_default()
        ));
    }
    let start = Instant::now();
    let mut rows = Vec::new();
    for c in &selected {
        let t = Instant::now();
        let row = runner.run(c).map_err(|e| format!("case {}: {e}", c.name))?;
        note(&format!(
            "{:<24} {:>7.1} s",
            c.name,
            t.elapsed().as_secs_f64()
        ));
        rows.push(row);
    }
    let failed: Vec<_> = rows.iter().filter(|r| !r.failures().is_empty()).collect();
    // A closed pipe only stops the printing: failed cases still fail the run.
    print_out(&format!(
        "{}\n{} cases, {} failed, {:.0} s ({:?} budget: {} eval walks, {} albedo walks per engine, divided by each case's cost)\n",
        format_table(&rows),
        rows.len(),
        failed.len(),
        start.elapsed().as_secs_f64(),
        if args.quick { "quick" } else { "full" },
        budget.eval_walks,
        budget.albedo_walks,
    ))?;
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "failed: {}",
            failed.iter().map(|r| r.name).collect::<Vec<_>>().join(", ")
        ))
    }
}
