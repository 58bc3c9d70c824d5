//! Loading nuScenes-format tables (nuScenes itself or any data set in its layout) into ground
//! truth; every error names the table, row and field.

use super::*;

/// Why the tables could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The directory does not exist.
    #[error("{0}: no such directory (give --dataroot DIR --version NAME so that DIR/NAME holds the nuScenes tables)")]
    MissingDir(PathBuf),
    /// A required table file is absent.
    #[error("{path}: missing table '{table}'")]
    MissingTable {
        /// The file that was expected.
        path: PathBuf,
        /// The table name.
        table: &'static str,
    },
    /// A table is unreadable or not a JSON array.
    #[error("{path}: {message}")]
    BadTable {
        /// The table file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A record lacks a field or has the wrong type.
    #[error("{path}: record {index}: field '{field}': {message}")]
    BadField {
        /// The table file.
        path: PathBuf,
        /// Record index.
        index: usize,
        /// The field.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
}

struct Table {
    path: PathBuf,
    rows: Vec<Value>,
}

impl Table {
    fn load(dir: &Path, name: &'static str, required: bool) -> Result<Option<Table>, LoadError> {
        let path = dir.join(format!("{name}.json"));
        if !path.exists() {
            return if required {
                Err(LoadError::MissingTable { path, table: name })
            } else {
                Ok(None)
            };
        }
        let text = std::fs::read_to_string(&path).map_err(|e| LoadError::BadTable {
            path: path.clone(),
            message: format!("cannot read: {e}"),
        })?;
        let v: Value = serde_json::from_str(&text).map_err(|e| LoadError::BadTable {
            path: path.clone(),
            message: format!("not valid JSON: {e}"),
        })?;
        match v {
            Value::Array(rows) => Ok(Some(Table { path, rows })),
            _ => Err(LoadError::BadTable {
                path,
                message: "expected a JSON array of records".into(),
            }),
        }
    }

    fn err(&self, index: usize, field: &'static str, message: &str) -> LoadError {
        LoadError::BadField {
            path: self.path.clone(),
            index,
            field,
            message: message.into(),
        }
    }

    fn str(&self, i: usize, field: &'static str) -> Result<&str, LoadError> {
        self.rows[i]
            .get(field)
            .ok_or_else(|| self.err(i, field, "missing"))?
            .as_str()
            .ok_or_else(|| self.err(i, field, "expected a string"))
    }

    fn u64(&self, i: usize, field: &'static str) -> Result<u64, LoadError> {
        self.rows[i]
            .get(field)
            .ok_or_else(|| self.err(i, field, "missing"))?
            .as_u64()
            .ok_or_else(|| self.err(i, field, "expected a non-negative integer"))
    }

    fn nums<const N: usize>(&self, i: usize, field: &'static str) -> Result<[f64; N], LoadError> {
        let arr = self.rows[i]
            .get(field)
            .ok_or_else(|| self.err(i, field, "missing"))?
            .as_array()
            .ok_or_else(|| self.err(i, field, "expected an array"))?;
        if arr.len() != N {
            return Err(self.err(
                i,
                field,
                &format!("expected {N} numbers, found {}", arr.len()),
            ));
        }
        let mut out = [0.0; N];
        for (k, v) in arr.iter().enumerate() {
            out[k] = v
                .as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| self.err(i, field, "expected finite numbers"))?;
        }
        Ok(out)
    }
}

/// Loads nuScenes tables from `dataroot/version`.
pub fn load_nuscenes(dataroot: &Path, version: &str) -> Result<GroundTruth, LoadError> {
    let dir = dataroot.join(version);
    if !dir.is_dir() {
        return Err(LoadError::MissingDir(dir));
    }
    let scene = Table::load(&dir, "scene", true)?.expect("required");
    let sample = Table::load(&dir, "sample", true)?.expect("required");
    let ann = Table::load(&dir, "sample_annotation", true)?.expect("required");
    let instance = Table::load(&dir, "instance", true)?.expect("required");
    let category = Table::load(&dir, "category", true)?.expect("required");
    let sample_data = Table::load(&dir, "sample_data", false)?;
    let ego_pose = Table::load(&dir, "ego_pose", false)?;

    let category_of = instance_categories(&category, &instance)?;
    let mut scene_index: HashMap<&str, usize> = HashMap::new();
    let mut scenes = Vec::new();
    for i in 0..scene.rows.len() {
        scene_index.insert(scene.str(i, "token")?, i);
        scenes.push(scene.str(i, "name")?.to_string());
    }
    let ego_of_sample = ego_by_sample(sample_data.as_ref(), ego_pose.as_ref())?;
    let mut frames = Vec::with_capacity(sample.rows.len());
    let mut frame_of: HashMap<&str, usize> = HashMap::new();
    for i in 0..sample.rows.len() {
        let token = sample.str(i, "token")?;
        let sc = sample.str(i, "scene_token")?;
        let scene = *scene_index
            .get(sc)
            .ok_or_else(|| sample.err(i, "scene_token", &format!("'{sc}' is not in scene.json")))?;
        frame_of.insert(token, frames.len());
        frames.push(GtFrame {
            sample_token: token.to_string(),
            scene,
            timestamp_us: sample.u64(i, "timestamp")?,
            ego: ego_of_sample.get(token).copied(),
            objects: Vec::new(),
        });
    }
    let mut tokens = TokenTable::new();
    let mut skipped: BTreeMap<String, usize> = BTreeMap::new();
    for i in 0..ann.rows.len() {
        let s = ann.str(i, "sample_token")?;
        let f = *frame_of
            .get(s)
            .ok_or_else(|| ann.err(i, "sample_token", &format!("'{s}' is not in sample.json")))?;
        let inst = ann.str(i, "instance_token")?;
        let name = *category_of.get(inst).ok_or_else(|| {
            ann.err(
                i,
                "instance_token",
                &format!("'{inst}' is not in instance.json"),
            )
        })?;
        let Some(class) = Class::from_category(name) else {
            *skipped.entry(name.to_string()).or_default() += 1;
            continue;
        };
        frames[f]
            .objects
            .push(annotation(&ann, i, tokens.intern(inst), class)?);
    }
    let tracks = tracks_with_velocities(&mut frames, scenes.len());
    frames.sort_by(|a, b| {
        (a.scene, a.timestamp_us, &a.sample_token).cmp(&(b.scene, b.timestamp_us, &b.sample_token))
    });
    Ok(GroundTruth {
        scenes,
        frames,
        tokens,
        skipped,
        motion: Motion::Tracks(tracks),
        recorded: None,
    })
}

/// Annotation `i` as the object `id` of `class`, its size checked.
fn annotation(ann: &Table, i: usize, id: u32, class: Class) -> Result<GtObject, LoadError> {
    let center = ann.nums::<3>(i, "translation")?;
    let [w, l, h] = ann.nums::<3>(i, "size")?;
    if w <= 0.0 || l <= 0.0 || h <= 0.0 {
        return Err(ann.err(i, "size", "sizes must be positive"));
    }
    let q = ann.nums::<4>(i, "rotation")?;
    Ok(GtObject {
        id,
        class,
        center,
        size: [l, w, h],
        yaw: wrap_angle(quaternion_yaw(q)),
        velocity: None,
    })
}

/// Each instance's category name, by instance token.
fn instance_categories<'t>(
    category: &'t Table,
    instance: &'t Table,
) -> Result<HashMap<&'t str, &'t str>, LoadError> {
    let mut name_of: HashMap<&str, &str> = HashMap::new();
    for i in 0..category.rows.len() {
        name_of.insert(category.str(i, "token")?, category.str(i, "name")?);
    }
    let mut out = HashMap::new();
    for i in 0..instance.rows.len() {
        let c = instance.str(i, "category_token")?;
        let name = name_of.get(c).ok_or_else(|| {
            let what = format!("'{c}' is not in category.json");
            instance.err(i, "category_token", &what)
        })?;
        out.insert(instance.str(i, "token")?, *name);
    }
    Ok(out)
}

/// Ego positions by sample token, through the key-frame `sample_data` records, when both
/// tables are present.
fn ego_by_sample(
    sample_data: Option<&Table>,
    ego_pose: Option<&Table>,
) -> Result<HashMap<String, [f64; 3]>, LoadError> {
    let mut out = HashMap::new();
    let (Some(sd), Some(ep)) = (sample_data, ego_pose) else {
        return Ok(out);
    };
    let mut pose: HashMap<&str, [f64; 3]> = HashMap::new();
    for i in 0..ep.rows.len() {
        pose.insert(ep.str(i, "token")?, ep.nums::<3>(i, "translation")?);
    }
    for i in 0..sd.rows.len() {
        let key = sd.rows[i]
            .get("is_key_frame")
            .and_then(Value::as_bool)
            .unwrap_or(true);
        if !key {
            continue;
        }
        let s = sd.str(i, "sample_token")?;
        let e = sd.str(i, "ego_pose_token")?;
        if let Some(p) = pose.get(e) {
            out.entry(s.to_string()).or_insert(*p);
        }
    }
    Ok(out)
}

/// Each object's annotations per scene in time order, and every annotation's velocity as the
/// devkit computes it (set on the frames' objects too).
fn tracks_with_velocities(
    frames: &mut [GtFrame],
    scenes: usize,
) -> Vec<BTreeMap<u32, Vec<TrackPoint>>> {
    let mut tracks: Vec<BTreeMap<u32, Vec<TrackPoint>>> = vec![BTreeMap::new(); scenes];
    for f in frames.iter() {
        for o in &f.objects {
            tracks[f.scene].entry(o.id).or_default().push(TrackPoint {
                t_us: f.timestamp_us,
                object: o.clone(),
            });
        }
    }
    for scene in &mut tracks {
        for track in scene.values_mut() {
            track.sort_by_key(|p| p.t_us);
            let pos: Vec<(u64, [f64; 3])> =
                track.iter().map(|p| (p.t_us, p.object.center)).collect();
            for (i, p) in track.iter_mut().enumerate() {
                p.object.velocity = devkit_velocity(&pos, i);
            }
        }
    }
    let velocity: HashMap<(usize, u32, u64), Option<[f64; 2]>> = tracks
        .iter()
        .enumerate()
        .flat_map(|(sc, scene)| {
            scene
                .values()
                .flatten()
                .map(move |p| ((sc, p.object.id, p.t_us), p.object.velocity))
        })
        .collect();
    for f in frames.iter_mut() {
        for o in &mut f.objects {
            o.velocity = velocity[&(f.scene, o.id, f.timestamp_us)];
        }
    }
    tracks
}
