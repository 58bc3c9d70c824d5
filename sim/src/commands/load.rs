//! `v2x-sim load`: the fuser under load, on a runtime of its own.

use v2x_sim::load::LoadArgs;
use v2x_sim::table::{markdown, Align::Left};

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
    if args.format.format == v2x_sim::table::Format::Json {
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
        let ms = |v: Option<f64>| v.unwrap_or(f64::NAN);
        let columns = [
            ("fusers", Left),
            ("tile (m)", Left),
            ("boxes in/s", Left),
            ("boxes fused/s", Left),
            ("windows (incomplete)", Left),
            ("captures incomplete", Left),
            ("windows lost", Left),
            ("fusion p50 / p99 (ms)", Left),
            ("e2e p99 (ms), worst fuser", Left),
            ("CPU %", Left),
        ];
        let cells = rows.iter().map(|r| {
            vec![
                r.fusers.to_string(),
                r.tile_m.to_string(),
                format!("{:.0}", r.input_boxes_per_s),
                format!("{:.0}", r.fused_boxes_per_s),
                format!("{} ({})", r.windows, r.windows_incomplete),
                r.captures_incomplete.to_string(),
                r.windows_lost.to_string(),
                format!(
                    "{:.3} / {:.3}",
                    ms(r.fusion_latency_ms.p50_ms),
                    ms(r.fusion_latency_ms.p99_ms)
                ),
                format!("{:.1}", ms(r.e2e_p99_ms)),
                format!("{:.0}", r.cpu_percent),
            ]
        });
        print!("{}", markdown(&columns, cells));
    }
    Ok(())
}

/// `--max-load`: each load tried, and the largest held.
fn max_load(rt: &tokio::runtime::Runtime, args: &LoadArgs) -> anyhow::Result<()> {
    let (runs, stopped) = rt.block_on(v2x_sim::load::run_max_load(args))?;
    if let Some(why) = &stopped {
        eprintln!("the search stopped early: {why}");
    }
    if args.format.format == v2x_sim::table::Format::Json {
        let v: Vec<_> = runs
            .iter()
            .map(|(r, held)| serde_json::json!({"held": held, "report": r}))
            .collect();
        let v = serde_json::json!({"runs": v, "stopped_early": stopped});
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let held = format!("held (p99 < {} ms)", v2x_sim::load::HOLD_P99_MS);
        let columns = [
            ("agents", Left),
            ("objects", Left),
            ("boxes/s", Left),
            ("windows", Left),
            ("fusion p99 (ms)", Left),
            (held.as_str(), Left),
        ];
        let cells = runs.iter().map(|(r, held)| {
            vec![
                r.agents.to_string(),
                r.objects.to_string(),
                format!("{:.0}", (r.agents * r.objects) as f64 * r.hz),
                format!("{} of {}", r.windows, r.frames_per_agent),
                format!("{:.3}", r.fusion_latency_ms.p99_ms.unwrap_or(f64::NAN)),
                (if *held { "yes" } else { "no" }).to_string(),
            ]
        });
        print!("{}", markdown(&columns, cells));
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
    if args.format.format == v2x_sim::table::Format::Json {
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
        let latencies = [
            ("fusion (window close to publish)", &r.fusion_latency_ms),
            ("fusion, first half", &r.fusion_latency_first_half_ms),
            ("fusion, second half", &r.fusion_latency_second_half_ms),
            ("end to end (capture to publish)", &r.e2e_latency_ms),
        ];
        print!(
            "{}",
            markdown(
                &[("latency (ms)", Left), ("p50 / p95 / p99 / max", Left)],
                latencies.map(|(what, x)| vec![what.to_string(), l(x)]),
            )
        );
        println!(
            "bytes per agent frame: {:.0} as frames, {:.0} as ETSI CPMs",
            r.bytes.payload_bytes_per_frame, r.bytes.cpm_bytes_per_frame
        );
        println!("CPU {:.0}% of one core (whole process: agents, Zenoh and fuser); RSS {:.1} MiB at start, {:.1} MiB at the end", r.cpu_percent, r.rss_start_mib, r.rss_end_mib);
    }
    Ok(())
}
