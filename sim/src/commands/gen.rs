//! `v2x-sim gen`.

use anyhow::Context;
use v2x_protocol::nuscenes_json::write_results;
use v2x_sim::cli::DataArgs;
use v2x_sim::noise::NoiseSetting;

/// The options of `v2x-sim gen`.
#[derive(clap::Args)]
pub struct GenArgs {
    #[command(flatten)]
    pub data: DataArgs,
    /// Noise: mild, moderate, large, realistic, a mix such as mild+large (one per agent), or
    /// POS,SIZE,YAW_DEG, or labels (each object exactly as labelled, stating 0.5 m, 0.2 m and
    /// 0.1 rad) [default: mild+large; with --dataset dair-v2x: labels, each side's own; with
    /// --dataset v2v4real none applies: the cars' own detections are written].
    #[arg(long)]
    pub noise: Option<String>,
    /// Detector faults, replacing the noise profile's own (none, except for `realistic`):
    /// `none`, `realistic`, or KEY=VALUE,... (keys below); one for all agents or one per
    /// agent joined by '+'.
    #[arg(long)]
    pub faults: Option<String>,
    /// The stds each agent states with its boxes, replacing its noise's own: `honest` (the
    /// default), `xK` (the noise's stds times K: x6 six times too wide, x0.17 six times too
    /// narrow), a profile or POS,SIZE,YAW_DEG (e.g. `mild` for a large-noise agent: an
    /// overconfident detector), or `none` (no std fields in its file); one for all agents or
    /// one per agent joined by '+'.
    #[arg(long)]
    pub stated_std: Option<String>,
    /// Number of agents.
    #[arg(long, default_value_t = 2)]
    pub agents: usize,
    #[command(flatten)]
    pub draw: v2x_sim::cli::DrawArgs,
    /// Capture rate of each agent in Hz, comma-separated, or one for all (default: the
    /// data's rate, on its frames).
    #[arg(long)]
    pub agent_hz: Option<String>,
    /// Phase of each agent in ms after each scene's first frame, comma-separated, or one
    /// for all (default 0).
    #[arg(long)]
    pub phase_ms: Option<String>,
    #[command(flatten)]
    pub out: v2x_protocol::cli::Output,
}

/// Runs `v2x-sim gen`.
pub fn run(args: GenArgs) -> anyhow::Result<()> {
    let GenArgs {
        data,
        noise,
        faults,
        stated_std,
        agents,
        draw: v2x_sim::cli::DrawArgs { seed, range },
        agent_hz,
        phase_ms,
        out: v2x_protocol::cli::Output { path: out },
    } = args;
    if data.is_v2v4real() {
        if noise.is_some()
            || faults.is_some()
            || stated_std.is_some()
            || range.is_some()
            || agent_hz.is_some()
            || phase_ms.is_some()
            || agents != 2
        {
            anyhow::bail!("--dataset v2v4real writes the two cars' own detections as they are: leave out --noise, --faults, --stated-std, --range, --agent-hz, --phase-ms and --agents");
        }
        return gen_v2v4real(&data, &out);
    }
    if data.is_dair() {
        if agent_hz.is_some() || phase_ms.is_some() || agents != 2 {
            anyhow::bail!("--agent-hz, --phase-ms and --agents do not apply to DAIR-V2X: its two agents capture at their recorded times");
        }
        let d = data.load_dair()?;
        let noise = noise.as_deref().unwrap_or("labels");
        let setting = setting_with_faults(noise, faults.as_deref(), stated_std.as_deref(), 2)?;
        std::fs::create_dir_all(&out)
            .with_context(|| format!("cannot create {}", out.display()))?;
        let files = v2x_sim::gen::generate_dair(&d, &setting, seed, range);
        for (a, r) in files.iter().enumerate() {
            let p = out.join(format!("agent{}.json", a + 1));
            write_agent(&p, r, &d.gt.tokens, &setting.agents[a])?;
            eprintln!(
                "wrote {} ({}, noise {})",
                p.display(),
                v2x_sim::dair::AGENTS[a],
                setting.agents[a].label
            );
        }
        eprintln!("{}", data.describe(&d.gt));
        return Ok(());
    }
    let gt = data.load()?;
    let noise = noise.as_deref().unwrap_or("mild+large");
    let setting = setting_with_faults(noise, faults.as_deref(), stated_std.as_deref(), agents)?;
    let timings = v2x_sim::gen::Timing::parse(
        agent_hz.as_deref(),
        phase_ms.as_deref(),
        setting.agents.len(),
    )?;
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let files = v2x_sim::gen::generate(&gt, &setting, &timings, seed, range);
    for (a, r) in files.iter().enumerate() {
        let p = out.join(format!("agent{}.json", a + 1));
        write_agent(&p, r, &gt.tokens, &setting.agents[a])?;
        eprintln!("wrote {} ({} noise)", p.display(), setting.agents[a].label);
    }
    eprintln!("{}", data.describe(&gt));
    Ok(())
}

/// V2V4Real's two cars' own detections, written as they are.
fn gen_v2v4real(data: &DataArgs, out: &std::path::Path) -> anyhow::Result<()> {
    let d = data.load_v2v4real(v2x_fuser::offline::kitti_default_std())?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let files = v2x_sim::gen::generate_v2v4real(&d, &Default::default());
    let tokens = v2x_protocol::nuscenes_json::TokenTable::new();
    for (k, r) in files.iter().enumerate() {
        let p = out.join(format!("agent{}.json", k + 1));
        write_results(&p, r, &tokens)?;
        eprintln!(
            "wrote {} ({}: {} frames, {} boxes, stds from each box's score)",
            p.display(),
            if k == 0 {
                "the ego car"
            } else {
                "car 1, in the ego car's frame"
            },
            r.samples.len(),
            r.samples.values().map(Vec::len).sum::<usize>()
        );
    }
    eprintln!(
        "V2V4Real {} split: fuse them with `v2x-fuser fuse --detector`, or replay them with `v2x-agent`",
        d.split
    );
    Ok(())
}

/// A noise setting for `agents` agents with the faults and stated stds given, if any.
fn setting_with_faults(
    noise: &str,
    faults: Option<&str>,
    stated: Option<&str>,
    agents: usize,
) -> anyhow::Result<NoiseSetting> {
    let mut setting = NoiseSetting::parse(noise, agents).map_err(anyhow::Error::msg)?;
    if let Some(f) = faults {
        setting
            .set_faults(f)
            .map_err(|e| anyhow::anyhow!("--faults: {e}"))?;
    }
    if let Some(s) = stated {
        setting
            .set_stated(s)
            .map_err(|e| anyhow::anyhow!("--stated-std: {e}"))?;
    }
    Ok(setting)
}

/// Writes one agent's results file, without std fields when the agent states none.
fn write_agent(
    path: &std::path::Path,
    r: &v2x_protocol::nuscenes_json::Results,
    tokens: &v2x_protocol::nuscenes_json::TokenTable,
    noise: &v2x_sim::noise::AgentNoise,
) -> anyhow::Result<()> {
    if noise.stated != v2x_truth::stated::Stated::Nothing {
        return Ok(write_results(path, r, tokens)?);
    }
    let mut doc = v2x_protocol::nuscenes_json::results_json(r, tokens);
    for b in doc["results"]
        .as_object_mut()
        .into_iter()
        .flat_map(|m| m.values_mut())
        .filter_map(|v| v.as_array_mut())
        .flatten()
        .filter_map(|b| b.as_object_mut())
    {
        for k in ["translation_std", "size_std", "yaw_std", "velocity_std"] {
            b.remove(k);
        }
    }
    std::fs::write(path, serde_json::to_string(&doc)?)
        .with_context(|| format!("cannot write {}", path.display()))
}
