//! `v2x-sim load`: the fuser under load, on a runtime of its own.

use v2x_sim::load::LoadArgs;

/// Runs `v2x-sim load`: one load, the same load on 1, 2 and 4 regional fusers, or the search for
/// the largest load one fuser holds.
pub fn run(args: LoadArgs) -> anyhow::Result<()> {
    let rt = v2x_protocol::net::runtime()?;
    if args.regions.is_some() {
        return regions(&rt, &args);
    }
    if args.max_load {
        return max_load(&rt, &args);
    }
    single(&rt, &args)
}

/// `--regions`: one table row per number of regional fusers.
fn regions(rt: &tokio::runtime::Runtime, args: &LoadArgs) -> anyhow::Result<()> {
    let rows = rt.block_on(v2x_sim::load::run_regions(args))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        println!(
            "{} agents x {} objects at {} Hz over four sites of {} m, {} s per configuration",
            args.agents,
            args.objects,
            args.hz,
            v2x_sim::load::BLOCK_M,
            args.seconds
        );
        println!("| fusers | tile (m) | boxes in/s | boxes fused/s | windows (incomplete) | captures incomplete | windows lost | fusion p50 / p99 (ms) | e2e p99 (ms), worst fuser | CPU % |\n|---|---|---|---|---|---|---|---|---|---|");
        for r in &rows {
            println!(
                "| {} | {} | {:.0} | {:.0} | {} ({}) | {} | {} | {:.3} / {:.3} | {:.1} | {:.0} |",
                r.fusers,
                r.tile_m,
                r.input_boxes_per_s,
                r.fused_boxes_per_s,
                r.windows,
                r.windows_incomplete,
                r.captures_incomplete,
                r.windows_lost,
                r.fusion_latency_ms.p50_ms.unwrap_or(f64::NAN),
                r.fusion_latency_ms.p99_ms.unwrap_or(f64::NAN),
                r.e2e_p99_ms.unwrap_or(f64::NAN),
                r.cpu_percent
            );
        }
    }
    Ok(())
}

/// `--max-load`: each load tried, and the largest held.
fn max_load(rt: &tokio::runtime::Runtime, args: &LoadArgs) -> anyhow::Result<()> {
    let (runs, stopped) = rt.block_on(v2x_sim::load::run_max_load(args))?;
    if let Some(why) = &stopped {
        eprintln!("the search stopped early: {why}");
    }
    if args.json {
        let v: Vec<_> = runs
            .iter()
            .map(|(r, held)| serde_json::json!({"held": held, "report": r}))
            .collect();
        let v = serde_json::json!({"runs": v, "stopped_early": stopped});
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("| agents | objects | boxes/s | windows | fusion p99 (ms) | held (p99 < {} ms) |\n|---|---|---|---|---|---|", v2x_sim::load::HOLD_P99_MS);
        for (r, held) in &runs {
            println!(
                "| {} | {} | {:.0} | {} of {} | {:.3} | {} |",
                r.agents,
                r.objects,
                (r.agents * r.objects) as f64 * r.hz,
                r.windows,
                r.frames_per_agent,
                r.fusion_latency_ms.p99_ms.unwrap_or(f64::NAN),
                if *held { "yes" } else { "no" }
            );
        }
        match runs.iter().rev().find(|(_, held)| *held) {
            Some((r, _)) => println!(
                "largest load held: {} agents x {} objects at {} Hz",
                r.agents, r.objects, r.hz
            ),
            None => println!("no load held: lower --agents"),
        }
    }
    Ok(())
}

/// One load: latencies over the run and its halves, CPU and memory.
fn single(rt: &tokio::runtime::Runtime, args: &LoadArgs) -> anyhow::Result<()> {
    let r = rt.block_on(v2x_sim::load::run(args))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        let l = |x: &v2x_fuser::node::Latency| {
            format!(
                "{:.3} / {:.3} / {:.3} / {:.3}",
                x.p50_ms.unwrap_or(f64::NAN),
                x.p95_ms.unwrap_or(f64::NAN),
                x.p99_ms.unwrap_or(f64::NAN),
                x.max_ms.unwrap_or(f64::NAN)
            )
        };
        println!("{} agents x {} objects at {} Hz: {} frames per agent, {} windows fused ({} incomplete), {} open at the end", r.agents, r.objects, r.hz, r.frames_per_agent, r.windows, r.windows_incomplete, r.open_windows_at_end);
        println!("| latency (ms) | p50 / p95 / p99 / max |\n|---|---|");
        println!(
            "| fusion (window close to publish) | {} |",
            l(&r.fusion_latency_ms)
        );
        println!(
            "| fusion, first half | {} |",
            l(&r.fusion_latency_first_half_ms)
        );
        println!(
            "| fusion, second half | {} |",
            l(&r.fusion_latency_second_half_ms)
        );
        println!(
            "| end to end (capture to publish) | {} |",
            l(&r.e2e_latency_ms)
        );
        println!("CPU {:.0}% of one core (whole process: agents, Zenoh and fuser); RSS {:.1} MiB at start, {:.1} MiB at the end", r.cpu_percent, r.rss_start_mib, r.rss_end_mib);
    }
    Ok(())
}
