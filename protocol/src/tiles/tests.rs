use super::*;

fn grid() -> Tiling {
    Tiling::new(200.0).unwrap()
}

#[test]
fn tiles_are_half_open_squares() {
    let g = grid();
    let t = |x: f64, y: f64| g.tile_of([x, y, 0.0]);
    assert_eq!(t(0.0, 0.0), Tile { x: 0, y: 0 });
    assert_eq!(t(199.999, 0.0), Tile { x: 0, y: 0 });
    assert_eq!(t(200.0, 0.0), Tile { x: 1, y: 0 });
    assert_eq!(t(-0.001, -200.0), Tile { x: -1, y: -1 });
    assert_eq!(t(-200.001, 399.0), Tile { x: -2, y: 1 });
    assert_eq!(
        t(1e300, -1e300),
        Tile {
            x: i32::MAX,
            y: i32::MIN
        }
    );
    assert!(Tiling::new(0.5).is_err());
    assert!(Tiling::new(f64::NAN)
        .unwrap_err()
        .to_string()
        .contains("tile size"));
}

#[test]
fn halos_reach_exactly_their_width() {
    let g = grid();
    let home = Tile { x: 0, y: 0 };
    let p = |x: f64, y: f64| [x, y, 0.0];
    assert!(g.within(home, p(-30.0, 100.0), 30.0));
    assert!(!g.within(home, p(-30.001, 100.0), 30.0));
    assert!(g.within(home, p(229.999, 229.999), 30.0));
    assert!(!g.within(home, p(230.0, 100.0), 30.0));
    assert!(g.within(home, p(0.0, 0.0), 0.0));
    assert!(!g.within(home, p(200.0, 0.0), 0.0));
    assert_eq!(g.with_halo(home, 0.0), vec![home]);
    let nine = g.with_halo(home, 30.0);
    assert_eq!(nine.len(), 9);
    assert!(nine.contains(&Tile { x: -1, y: 1 }));
    assert_eq!(g.with_halo(home, 250.0).len(), 25);
}

#[test]
fn tile_names_round_trip() {
    for t in [
        Tile { x: 0, y: 0 },
        Tile { x: -3, y: 12 },
        Tile { x: 7, y: -1 },
    ] {
        assert_eq!(t.to_string().parse::<Tile>().unwrap(), t);
        crate::keys::validate_chunk("tile", &t.to_string()).unwrap();
    }
    assert!("3"
        .parse::<Tile>()
        .unwrap_err()
        .to_string()
        .contains("COLUMN_ROW"));
    assert!("a_1".parse::<Tile>().is_err());
}

#[test]
fn tile_names_have_one_spelling() {
    for bad in ["+1_2", "01_2", "1_-0", "1_2_3", "1 _2", ""] {
        assert!(bad.parse::<Tile>().is_err(), "{bad}");
    }
}

#[test]
fn tile_lists_round_trip_and_reject_what_the_encoder_cannot_write() {
    let tiles = vec![
        Tile { x: -1, y: 0 },
        Tile { x: 0, y: -1 },
        Tile { x: 0, y: 0 },
    ];
    let bytes = encode_tiles(&tiles).unwrap();
    assert_eq!(bytes, b"-1_0 0_-1 0_0");
    assert_eq!(decode_tiles(&bytes).unwrap(), tiles);
    for bad in [
        &b""[..],
        b"0_0 0_0",
        b"1_0 0_0",
        b"0_0  1_0",
        b"0_0,1_0",
        b"\xff",
        b"0_0 ",
    ] {
        assert!(
            decode_tiles(bad).is_err(),
            "{:?}",
            String::from_utf8_lossy(bad)
        );
    }
    let many: Vec<Tile> = (0..=MAX_TILES_PER_CAPTURE as i32)
        .map(|x| Tile { x, y: 0 })
        .collect();
    assert!(encode_tiles(&many)
        .unwrap_err()
        .to_string()
        .contains("1 to 64"));
    assert!(decode_tiles(
        &many
            .iter()
            .map(Tile::to_string)
            .collect::<Vec<_>>()
            .join(" ")
            .into_bytes()
    )
    .is_err());
    assert!(encode_tiles(&many[..64]).is_ok());
    assert!(decode_tiles(&encode_tiles(&many[..64]).unwrap()).is_ok());
}

proptest::proptest! {
    /// Any bytes: a tile list or an error, never a panic; what decodes encodes back to the same
    /// bytes.
    #[test]
    fn any_attachment_decodes_or_is_refused(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..64)) {
        if let Ok(tiles) = decode_tiles(&bytes) {
            proptest::prop_assert_eq!(encode_tiles(&tiles).unwrap(), bytes);
        }
    }

    /// Any set of tiles: encoded, decoded, the same set.
    #[test]
    fn any_tile_set_round_trips(raw in proptest::collection::btree_set((proptest::prelude::any::<i32>(), proptest::prelude::any::<i32>()), 1..=64)) {
        let tiles: Vec<Tile> = raw.into_iter().map(|(x, y)| Tile { x, y }).collect();
        let bytes = encode_tiles(&tiles).unwrap();
        proptest::prop_assert_eq!(decode_tiles(&bytes).unwrap(), tiles);
    }
}

#[test]
fn a_points_border_distance_is_to_the_nearest_edge_of_its_tile() {
    let g = grid();
    assert_eq!(g.border_distance([0.0, 50.0]), 0.0);
    assert_eq!(g.border_distance([30.0, 100.0]), 30.0);
    assert_eq!(g.border_distance([190.0, 100.0]), 10.0);
    assert_eq!(g.border_distance([-5.0, -150.0]), 5.0);
    assert_eq!(g.border_distance([100.0, 100.0]), 100.0);
}
