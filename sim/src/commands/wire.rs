//! `v2x-sim wire`: a results file's frames as the standard message (ETSI CPM, UPER) or the
//! project's own frames, one file per agent and sample, with the bytes of both; or CPM files
//! read back as boxes.

use anyhow::{bail, Context};
use clap::ValueEnum;
use serde_json::json;
use std::path::{Path, PathBuf};
use v2x_cpm::Geo;
use v2x_protocol::nuscenes_json::{self, MissingStd, TokenTable};
use v2x_protocol::{wire, AgentKind, Frame};

/// What `v2x-sim wire` writes.
#[derive(Copy, Clone, Debug, ValueEnum, PartialEq)]
pub enum WireFormat {
    /// ETSI Collective Perception Messages (TS 103 324 Release 2), UPER: `<sample>.uper`.
    Cpm,
    /// The project's own frames (docs/wire-format.md): `<sample>.frame`.
    Frame,
}

/// The options of `v2x-sim wire`.
#[derive(clap::Args)]
pub struct WireArgs {
    /// Results files, one per agent (nuScenes results JSON with each sample's capture time in
    /// `meta.v2x_timestamps`, as `v2x-sim gen` writes them); with --read, CPM files.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The encoding written.
    #[arg(long, value_enum, default_value = "cpm")]
    pub format: WireFormat,
    /// The folder to write: PATH/<agent>/<sample>.uper (or .frame), the agent named by the
    /// file's `meta.v2x_agent`, else by the file's name (not with --read).
    #[arg(
        short = 'o',
        long = "output",
        visible_alias = "out",
        value_name = "PATH",
        required_unless_present = "read"
    )]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub map_origin: v2x_cpm::MapOrigin,
    /// An agent that is a roadside unit (its CPMs carry the RSU container); repeatable.
    #[arg(long = "rsu", value_name = "AGENT")]
    pub rsu: Vec<String>,
    /// Microseconds added to every capture time: a CPM's time is ITS time, from 2004-01-01, so
    /// a synthetic clock that starts at 0 needs placing after it.
    #[arg(long, default_value_t = 0)]
    pub time_offset_us: u64,
    /// Read the inputs as CPM files and print each one's boxes as JSON (one document per line).
    #[arg(long)]
    pub read: bool,
}

/// Runs `v2x-sim wire`.
pub fn run(args: WireArgs) -> anyhow::Result<()> {
    if args.read {
        return read(&args.inputs, &args.map_origin.geo);
    }
    let out = args
        .output
        .as_deref()
        .expect("clap requires --output without --read");
    println!("agent\tframes\tboxes/frame\tCPM bytes/frame\tframe bytes/frame");
    for path in &args.inputs {
        let (agent, frames) = frames_of(path, &args)?;
        let dir = out.join(&agent);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let (mut cpm_bytes, mut frame_bytes, mut boxes) = (0, 0, 0);
        for (sample, frame) in &frames {
            let cpm = v2x_cpm::encode(frame, &args.map_origin.geo).map_err(|e| {
                let hint = match e {
                    v2x_cpm::EncodeError::BeforeItsEpoch(_) => {
                        " (give --time-offset-us to place the data's clock after it)"
                    }
                    _ => "",
                };
                anyhow::anyhow!("{}: sample {sample}: {e}{hint}", path.display())
            })?;
            let own = wire::encode(frame)
                .with_context(|| format!("{}: sample {sample}", path.display()))?;
            cpm_bytes += cpm.len();
            frame_bytes += own.len();
            boxes += frame.detections.len();
            let (bytes, ext) = match args.format {
                WireFormat::Cpm => (cpm, "uper"),
                WireFormat::Frame => (own, "frame"),
            };
            let file = dir.join(format!("{sample}.{ext}"));
            std::fs::write(&file, bytes)
                .with_context(|| format!("cannot write {}", file.display()))?;
        }
        let n = frames.len().max(1) as f64;
        println!(
            "{agent}\t{}\t{:.1}\t{:.1}\t{:.1}",
            frames.len(),
            boxes as f64 / n,
            cpm_bytes as f64 / n,
            frame_bytes as f64 / n
        );
    }
    Ok(())
}

/// The agent a results file is from and its frames by sample, as the agent would send them
/// (fitted to the wire, the origin at the boxes' centroid).
fn frames_of(path: &Path, args: &WireArgs) -> anyhow::Result<(String, Vec<(String, Frame)>)> {
    let mut tokens = TokenTable::new();
    // Stds are carried as stated; a box without them goes as the mild setting's.
    let missing = MissingStd::Default(v2x_protocol::NoiseProfile::Mild.std());
    let results = nuscenes_json::read_results(path, &mut tokens, missing)?;
    let agent = results.meta["v2x_agent"]
        .as_str()
        .map(str::to_string)
        .or_else(|| Some(path.file_stem()?.to_str()?.to_string()))
        .with_context(|| format!("{}: cannot name the agent", path.display()))?;
    wire::check_agent_name(&agent)
        .map_err(|e| anyhow::anyhow!("{}: agent name: {e}", path.display()))?;
    let Some(times) = v2x_fuser::offline::capture_times(&results) else {
        bail!(
            "{}: no capture time for every sample (meta.v2x_timestamps, as `v2x-sim gen` writes)",
            path.display()
        );
    };
    let kind = if args.rsu.contains(&agent) {
        AgentKind::Infrastructure
    } else {
        AgentKind::Vehicle
    };
    let mut frames = Vec::new();
    for (seq, (sample, dets)) in results.in_file_order().enumerate() {
        if sample.is_empty() || sample.contains(['/', '\\']) || sample.starts_with('.') {
            bail!("{}: sample '{sample}' cannot name a file", path.display());
        }
        let mut frame = Frame {
            agent: agent.clone(),
            kind,
            seq: seq as u32,
            capture_us: times[sample] + args.time_offset_us,
            origin: [0.0; 3],
            detections: dets.clone(),
        }
        .with_centroid_origin();
        wire::fit(&mut frame);
        frames.push((sample.clone(), frame));
    }
    Ok((agent, frames))
}

/// Prints each CPM file's message as JSON: sender, time, reference position and boxes.
fn read(inputs: &[PathBuf], geo: &Geo) -> anyhow::Result<()> {
    let tokens = TokenTable::new();
    for path in inputs {
        let bytes =
            std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        let cpm = v2x_cpm::decode(&bytes, geo).with_context(|| path.display().to_string())?;
        let sample = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default();
        let doc = json!({
            "file": path.display().to_string(),
            "station_id": cpm.station_id,
            "kind": cpm.kind,
            "capture_us": cpm.capture_us,
            "origin": cpm.origin,
            "skipped": cpm.skipped.iter().map(|s| json!({"index": s.index, "reason": s.reason})).collect::<Vec<_>>(),
            "boxes": cpm.detections.iter().map(|d| nuscenes_json::box_json(sample, d, &tokens)).collect::<Vec<_>>(),
        });
        println!("{doc}");
    }
    Ok(())
}
