//! Offline tracking: the fused windows of files followed over time in time order, or each
//! agent's boxes through the tracks, per file or per KITTI sequence (`v2x-fuser track`).

use super::*;

/// Fused boxes followed over time: the tracked boxes per sample, each box's track id, and the
/// tracker's counters.
pub struct Tracks {
    /// Boxes as the tracks estimate them, per sample (the fused output's samples).
    pub results: Results,
    /// The track id of each box, in the same order.
    pub ids: BTreeMap<String, Vec<u32>>,
    /// Lifecycle counters at the end.
    pub stats: TrackStats,
}

/// Fuses the agents' files, then runs the tracker over the fused windows in time order. The
/// files must carry capture times (`meta.v2x_timestamps`, as `v2x-sim gen` writes them).
pub fn track_results(
    agents: &[Results],
    opts: &OfflineOptions,
    params: TrackerParams,
) -> Result<Tracks, FilesError> {
    if agents.is_empty() || !agents.iter().all(|r| capture_times(r).is_some()) {
        return Err(FilesError::NoCaptureTimes);
    }
    if params.guided() {
        return Ok(track_through(agents, opts, params));
    }
    let fused = fuse_results(agents, opts);
    let times = capture_times(&fused).expect("fusion by time stamps every sample");
    let mut order: Vec<(&u64, &String)> = fused.samples.keys().map(|s| (&times[s], s)).collect();
    order.sort();
    let mut tracker = Tracker::new(params);
    let mut results = Results {
        meta: fused.meta.clone(),
        ..Default::default()
    };
    let mut ids = BTreeMap::new();
    for (t, sample) in order {
        let (boxes, track_ids) = tracker
            .step(*t, &fused.samples[sample])
            .into_iter()
            .map(|tr| (tr.det, tr.tracking_id))
            .unzip();
        results.samples.insert(sample.clone(), boxes);
        ids.insert(sample.clone(), track_ids);
    }
    Ok(Tracks {
        results,
        ids,
        stats: tracker.stats(),
    })
}

/// Tracking through the tracks ([`Tracker::step_agents`]): each window's agents' boxes go to the
/// tracker directly, the options' method fusing between agents only the boxes no track explains.
fn track_through(agents: &[Results], opts: &OfflineOptions, params: TrackerParams) -> Tracks {
    let times: Vec<HashMap<String, u64>> = agents
        .iter()
        .map(|r| capture_times(r).expect("checked by the caller"))
        .collect();
    let mut tracker = Tracker::new(params);
    let mut results = Results {
        meta: agents[0].meta.clone(),
        ..Default::default()
    };
    let mut ids = BTreeMap::new();
    let meta = by_time(agents, &times, opts, |_, sample, prepared| {
        let (boxes, track_ids) = tracker
            .step_agents(prepared.t_ref, &prepared.lists, &opts.steps.method)
            .into_iter()
            .map(|tr| (tr.det, tr.tracking_id))
            .unzip();
        results.samples.insert(sample.clone(), boxes);
        ids.insert(sample.clone(), track_ids);
    });
    meta.set(&mut results);
    Tracks {
        results,
        ids,
        stats: tracker.stats(),
    }
}

/// Reads, fuses, tracks and writes tracking results (a nuScenes tracking file, or KITTI tracking
/// rows per sequence): the `v2x-fuser track` command. KITTI sequences are tracked one by one.
pub fn track_files(
    inputs: &[PathBuf],
    output: &std::path::Path,
    missing: MissingStd,
    opts: &OfflineOptions,
    params: TrackerParams,
    format: OutputFormat,
) -> Result<Tracks, FilesError> {
    let read = read_inputs(inputs, missing)?;
    let params = read.tracker_params(opts, params);
    let opts = &read.tracking_options(opts);
    let tracks = if read.sequences.is_empty() {
        track_results(&read.agents, opts, params)?
    } else {
        track_sequences(&read.agents, opts, params)?
    };
    match format.resolve(&read) {
        OutputFormat::Kitti => {
            kitti::write_track_dir(output, &tracks.results, &tracks.ids, read.sequences)?;
        }
        _ => {
            let doc = tracking_json(&tracks.results, &tracks.ids, &read.tokens);
            write_json(output, &doc)?;
        }
    }
    Ok(tracks)
}

/// Tracks each KITTI sequence on its own (a fresh tracker per sequence), joining the outputs:
/// what `v2x-fuser track` does with KITTI folders.
pub fn track_sequences(
    agents: &[Results],
    opts: &OfflineOptions,
    params: TrackerParams,
) -> Result<Tracks, FilesError> {
    let timed = || {
        let mut r = Results {
            meta: v2x_protocol::nuscenes_json::default_meta(),
            ..Default::default()
        };
        r.meta["v2x_timestamps"] = Value::Object(Default::default());
        r
    };
    let mut per_seq: BTreeMap<u32, Vec<Results>> = BTreeMap::new();
    for (k, agent) in agents.iter().enumerate() {
        for (token, dets) in &agent.samples {
            let (seq, _) = kitti::parse_token(token).expect("read from KITTI folders");
            let part = &mut per_seq
                .entry(seq)
                .or_insert_with(|| (0..agents.len()).map(|_| timed()).collect())[k];
            part.meta["v2x_timestamps"][token] = agent.meta["v2x_timestamps"][token].clone();
            part.samples.insert(token.clone(), dets.clone());
        }
    }
    let mut all = Tracks {
        results: Results {
            meta: agents.first().map(|a| a.meta.clone()).unwrap_or_default(),
            ..Default::default()
        },
        ids: BTreeMap::new(),
        stats: TrackStats::default(),
    };
    for parts in per_seq.into_values() {
        let t = track_results(&parts, opts, params)?;
        all.results.samples.extend(t.results.samples);
        all.ids.extend(t.ids);
        all.stats.births += t.stats.births;
        all.stats.deaths += t.stats.deaths;
        all.stats.live += t.stats.live;
    }
    Ok(all)
}
