//! Writing KITTI rows: one NNNN.txt per sequence of detection or tracking rows.

use super::*;

/// Groups boxes by the sequence their sample token names; a token of another form is an error.
fn by_sequence<'a, T>(
    dir: &Path,
    samples: impl Iterator<Item = (&'a String, T)>,
) -> Result<BTreeMap<u32, Vec<(u32, T)>>, KittiError> {
    let mut out: BTreeMap<u32, Vec<(u32, T)>> = BTreeMap::new();
    for (t, v) in samples {
        let (seq, frame) = parse_token(t).ok_or_else(|| KittiError {
            file: dir.to_path_buf(),
            line: None,
            field: None,
            message: format!(
                "sample '{t}' names no sequence and frame (SSSS_FFFFFF): \
                 the KITTI layout needs inputs read from it"
            ),
        })?;
        out.entry(seq).or_default().push((frame, v));
    }
    for v in out.values_mut() {
        v.sort_by_key(|(f, _)| *f);
    }
    Ok(out)
}

fn write_sequences(
    dir: &Path,
    files: BTreeMap<u32, Vec<String>>,
    all: impl IntoIterator<Item = u32>,
) -> Result<usize, KittiError> {
    let err = |file: PathBuf, e: std::io::Error| KittiError {
        file,
        line: None,
        field: None,
        message: format!("cannot write: {e}"),
    };
    std::fs::create_dir_all(dir).map_err(|e| err(dir.to_path_buf(), e))?;
    let mut written = 0;
    let mut seqs: std::collections::BTreeSet<u32> = all.into_iter().collect();
    seqs.extend(files.keys());
    for seq in seqs {
        let path = dir.join(format!("{seq:04}.txt"));
        let lines = files.get(&seq).map(Vec::as_slice).unwrap_or_default();
        let mut text = lines.join("\n");
        if !text.is_empty() {
            text.push('\n');
        }
        std::fs::write(&path, text).map_err(|e| err(path.clone(), e))?;
        written += lines.len();
    }
    Ok(written)
}

/// Writes results as detection rows, one `NNNN.txt` per sequence in `dir` (also one, empty, for
/// each of `sequences` without a box); boxes of a class the layout lacks are left out. Returns
/// the rows written.
pub fn write_detection_dir(
    dir: &Path,
    results: &Results,
    sequences: impl IntoIterator<Item = u32>,
) -> Result<usize, KittiError> {
    let mut files = BTreeMap::new();
    for (seq, frames) in by_sequence(dir, results.samples.iter())? {
        let lines: Vec<String> = frames
            .into_iter()
            .flat_map(|(frame, dets)| {
                dets.iter()
                    .filter(|d| kitti_type(d.class).is_some())
                    .map(move |d| {
                        DetectionRow {
                            frame,
                            class: d.class,
                            score: d.score,
                            bbox: KittiBox {
                                center: d.center,
                                size: d.size,
                                yaw: d.yaw,
                            },
                        }
                        .write()
                    })
            })
            .collect();
        files.insert(seq, lines);
    }
    write_sequences(dir, files, sequences)
}

/// Writes tracked boxes as tracking rows (`ids[sample][k]` the track of box k), one `NNNN.txt`
/// per sequence in `dir` (also one, empty, for each of `sequences` without a box), as
/// AB3DMOT's evaluator reads them. Returns the rows written.
pub fn write_track_dir(
    dir: &Path,
    results: &Results,
    ids: &BTreeMap<String, Vec<u32>>,
    sequences: impl IntoIterator<Item = u32>,
) -> Result<usize, KittiError> {
    let mut files = BTreeMap::new();
    let samples = results
        .samples
        .iter()
        .map(|(t, dets)| (t, (dets, ids.get(t).map(Vec::as_slice).unwrap_or_default())));
    for (seq, frames) in by_sequence(dir, samples)? {
        let lines: Vec<String> = frames
            .into_iter()
            .flat_map(|(frame, (dets, ids))| {
                dets.iter()
                    .zip(ids)
                    .filter(|(d, _)| kitti_type(d.class).is_some())
                    .map(move |(d, &id)| {
                        TrackRow {
                            frame,
                            id,
                            class: d.class,
                            bbox: KittiBox {
                                center: d.center,
                                size: d.size,
                                yaw: d.yaw,
                            },
                            score: Some(d.score),
                        }
                        .write()
                    })
            })
            .collect();
        files.insert(seq, lines);
    }
    write_sequences(dir, files, sequences)
}
