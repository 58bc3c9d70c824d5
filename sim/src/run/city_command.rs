//! `v2x-sim run` of a city scenario: every role here, or the named ones.

use super::*;

/// `v2x-sim run` of a city scenario: every role here, or the named ones.
pub(super) async fn run_city_command(
    args: &RunArgs,
    scenario: &Scenario,
    regions: &crate::scenario::RegionsSpec,
    gt: &GroundTruth,
) -> anyhow::Result<()> {
    let names = city::city_roles(scenario, regions);
    for r in &args.roles {
        if !names.contains(r) {
            bail!(
                "--role {r}: not a role of this city scenario (roles: {})",
                names.join(", ")
            );
        }
    }
    if args.viz.mcap.is_some() || args.viz.foxglove.is_some() || args.timeline.is_some() {
        bail!("--mcap, --foxglove and --timeline show one fuser; a city scenario has several");
    }
    let schedule = Schedule::of(gt, scenario.duration_s);
    let stop = stop_on_signal();
    let (summary, outcome) = if args.roles.is_empty() {
        eprintln!(
            "running {} routers, {} regional fusers and {} agents in this process over loopback ({} frames)...",
            regions.routers.len(),
            regions.fusers.len(),
            scenario.agents.len(),
            schedule.frames.len()
        );
        let (summary, outcome, _) = city::run_city_local(scenario, gt, stop).await?;
        (Some(summary), Some(outcome))
    } else {
        city_roles_here(args, scenario, regions, gt, &schedule, stop).await?
    };
    if let (Some(path), Some(outcome)) = (&args.record, &outcome) {
        record(path, gt, &schedule, outcome)?;
    }
    match summary {
        Some(s) => print_summary(&s, args.format),
        None => Ok(()),
    }
}

/// The named roles of a city scenario run here: the city's summary when every region ran here,
/// else the regions' own figures printed, and the joined outcome of the fusers that ran here.
async fn city_roles_here(
    args: &RunArgs,
    scenario: &Scenario,
    regions: &crate::scenario::RegionsSpec,
    gt: &GroundTruth,
    schedule: &Schedule,
    stop: watch::Receiver<bool>,
) -> anyhow::Result<(Option<Summary>, Option<FuserOutcome>)> {
    let start = std::time::Instant::now();
    let here = city::run_city_roles(scenario, gt, schedule, &args.roles, stop).await?;
    if here.fusers.is_empty() {
        if !here.agents.is_empty() {
            report_agents_alone(scenario, schedule, &here.agents, args.format)?;
        }
        return Ok((None, None));
    }
    let all_here = here.fusers.len() == regions.fusers.len();
    let reports: Vec<_> = here.fusers.iter().map(|(_, r, _)| r.clone()).collect();
    let outcome = city::join(here.fusers.into_iter().map(|(_, _, o)| o).collect());
    if all_here {
        // Every region ran here: the city's summary.
        let elapsed = start.elapsed().as_secs_f64();
        let mut s = summarize(scenario, gt, schedule, &outcome, &here.agents, elapsed);
        s.regions = reports;
        return Ok((Some(s), Some(outcome)));
    }
    // Some regions: their own figures (scored, the regions' recordings joined, by
    // `v2x-sim eval`).
    match args.format {
        RunFormat::Json => println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "namespace": scenario.namespace,
                "regions": reports,
            }))?
        ),
        RunFormat::Table => tables::print_regions(&reports),
    }
    Ok((None, Some(outcome)))
}
