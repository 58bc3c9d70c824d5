//! The loader on the project's DAIR-V2X fixtures (`fixtures/dair/make.py` says how every number
//! in them was chosen).

use super::*;
use std::f64::consts::{FRAC_PI_2, PI};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/dair")
        .join(name)
}

fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < tol)
}

#[test]
fn dair_v2x_c_lands_every_side_on_the_world_boxes_with_the_offset() {
    let d = load_dair(&fixture("dair-v2x-c"), true).unwrap();
    assert_eq!(d.layout, Layout::Cooperative);
    assert_eq!(d.gt.scenes, ["b1"]);
    // Frames in capture order although the pairs are listed backwards.
    let tokens: Vec<&str> =
        d.gt.frames
            .iter()
            .map(|f| f.sample_token.as_str())
            .collect();
    assert_eq!(tokens, ["000010", "000011", "000012"]);
    let p = &d.rec.pairs[1];
    assert_eq!(
        (p.veh_frame.as_str(), p.inf_frame.as_str()),
        ("000011", "001011")
    );
    assert_eq!(p.veh_us - p.inf_us, 20_000);
    assert_eq!(p.offset, [0.5, -0.3]);
    // Vehicle LiDAR origin: R90 (1, 0, 1.5) + (1000, 2001, 10) = (1000, 2002, 11.5).
    assert!(close(
        p.veh_to_world.translation,
        [1000.0, 2002.0, 11.5],
        1e-12
    ));
    assert_eq!(d.gt.frames[1].ego, Some([1000.0, 2002.0, 11.5]));
    // The world labels: car A, truck B, van C (a car), read from their corners.
    let gt = &d.gt.frames[1].objects;
    assert_eq!(gt.len(), 3);
    assert_eq!(
        gt.iter().map(|o| o.class).collect::<Vec<_>>(),
        [Class::Car, Class::Truck, Class::Car]
    );
    assert!(close(gt[0].center, [1000.0, 2011.0, 10.5], 1e-9));
    assert!(close(gt[0].size, [4.5, 1.9, 1.6], 1e-9));
    assert!((gt[0].yaw - FRAC_PI_2).abs() < 1e-9);
    assert!((gt[1].yaw).abs() < 1e-9);
    // Each side's car A on the world's: the vehicle's through its chain, the roadside's
    // through its half turn plus the offset.
    let (veh, inf) = (&d.rec.veh[1], &d.rec.inf[1]);
    assert_eq!(veh.len(), 2);
    assert_eq!(
        inf.len(),
        3,
        "car, truck and pedestrian; the barrow is skipped"
    );
    for side in [&veh[0], &inf[0]] {
        assert!(close(side.center, gt[0].center, 1e-9), "{:?}", side.center);
        assert!((wrap_angle(side.yaw - gt[0].yaw)).abs() < 1e-9);
        assert_eq!(side.size, [4.5, 1.9, 1.6]);
    }
    assert!(close(inf[1].center, gt[1].center, 1e-9));
    assert!(close(veh[1].center, gt[2].center, 1e-9));
    assert_eq!(inf[2].class, Class::Pedestrian);
    assert_eq!(
        d.gt.skipped.get("Barrowlist"),
        None,
        "the cooperative labels hold no barrow"
    );
    // Unique ids per world box.
    let ids: std::collections::HashSet<u32> =
        d.gt.frames
            .iter()
            .flat_map(|f| f.objects.iter().map(|o| o.id))
            .collect();
    assert_eq!(ids.len(), 9);
}

#[test]
fn without_the_offset_the_roadside_is_off_by_it() {
    let d = load_dair(&fixture("dair-v2x-c"), false).unwrap();
    let (car, world) = (&d.rec.inf[0][0], &d.gt.frames[0].objects[0]);
    assert!(close(
        car.center,
        [
            world.center[0] - 0.5,
            world.center[1] + 0.3,
            world.center[2]
        ],
        1e-9
    ));
    // The vehicle does not move with the offset.
    assert!(close(d.rec.veh[0][0].center, world.center, 1e-9));
}

#[test]
fn v2x_seq_spd_tracks_keep_their_ids_and_its_offset_turns_with_the_vehicle() {
    let d = load_dair(&fixture("v2x-seq-spd"), true).unwrap();
    assert_eq!(d.layout, Layout::Sequential);
    assert_eq!(d.gt.scenes, ["s1"]);
    for (k, f) in d.gt.frames.iter().enumerate() {
        // Car A drives north 1 m a frame with the vehicle.
        assert!(close(
            f.objects[0].center,
            [1000.0, 2011.0 + k as f64, 10.5],
            1e-9
        ));
        assert!((f.objects[0].yaw - FRAC_PI_2).abs() < 1e-9);
        assert!((f.objects[1].yaw).abs() < 1e-9 || (f.objects[1].yaw.abs() - PI).abs() < 1e-9);
        // The roadside's car A lands on it only with the offset turned into the world.
        assert!(
            close(d.rec.inf[k][0].center, f.objects[0].center, 1e-9),
            "{:?}",
            d.rec.inf[k][0].center
        );
    }
    let ids: Vec<u32> = d.gt.frames.iter().map(|f| f.objects[0].id).collect();
    assert!(
        ids.windows(2).all(|w| w[0] == w[1]),
        "one track id, one object"
    );
    assert_ne!(d.gt.frames[0].objects[0].id, d.gt.frames[0].objects[1].id);
    let off = load_dair(&fixture("v2x-seq-spd"), false).unwrap();
    // R90 (0.5, -0.3) = (0.3, 0.5) in the world.
    let (a, b) = (off.rec.inf[0][0].center, d.rec.inf[0][0].center);
    assert!(close(
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
        [0.3, 0.5, 0.0],
        1e-9
    ));
}

#[test]
fn bad_input_names_the_file_record_and_field() {
    let dir = std::env::temp_dir().join(format!("dair-bad-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    // Missing directories.
    let e = load_dair(&dir, true).unwrap_err().to_string();
    assert!(e.contains("cooperative") && e.contains("--dataroot"), "{e}");
    // A pair naming a vehicle frame the side does not have; a world box that is no box.
    let src = fixture("dair-v2x-c");
    copy_dir(&src, &dir);
    let pairs = dir.join("cooperative/data_info.json");
    let text = std::fs::read_to_string(&pairs).unwrap();
    std::fs::write(
        &pairs,
        text.replacen("velodyne/000012.pcd", "velodyne/000099.pcd", 1),
    )
    .unwrap();
    let e = load_dair(&dir, true).unwrap_err().to_string();
    assert!(
        e.contains("data_info.json")
            && e.contains("record 0")
            && e.contains("vehicle_pointcloud_path")
            && e.contains("000099"),
        "{e}"
    );
    std::fs::write(&pairs, text).unwrap();
    let label = dir.join("cooperative/label_world/000011.json");
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&label).unwrap()).unwrap();
    v[1]["world_8_points"][6][0] = Value::from(1.0e3);
    std::fs::write(&label, v.to_string()).unwrap();
    let e = load_dair(&dir, true).unwrap_err().to_string();
    assert!(
        e.contains("000011.json")
            && e.contains("record 1")
            && e.contains("world_8_points")
            && e.contains("not a box"),
        "{e}"
    );
    // A world label whose fields disagree with its corners: counted, the corners used.
    let _ = std::fs::remove_dir_all(&dir);
    copy_dir(&src, &dir);
    let label = dir.join("cooperative/label_world/000010.json");
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&label).unwrap()).unwrap();
    v[0]["3d_location"]["x"] = Value::from(1001.0);
    std::fs::write(&label, v.to_string()).unwrap();
    let d = load_dair(&dir, true).unwrap();
    assert_eq!(d.corner_mismatches, 1);
    assert!(close(
        d.gt.frames[0].objects[0].center,
        [1000.0, 2011.0, 10.5],
        1e-9
    ));
    assert_eq!(load_dair(&src, true).unwrap().corner_mismatches, 0);
    // A timestamp that is no number.
    let _ = std::fs::remove_dir_all(&dir);
    copy_dir(&src, &dir);
    let info = dir.join("vehicle-side/data_info.json");
    let text = std::fs::read_to_string(&info).unwrap();
    std::fs::write(&info, text.replacen("\"1626155123100000\"", "\"soon\"", 2)).unwrap();
    let e = load_dair(&dir, true).unwrap_err().to_string();
    assert!(
        e.contains("pointcloud_timestamp") && e.contains("record 1"),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).unwrap();
        }
    }
}
