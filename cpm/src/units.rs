//! The message's units: its quantisation rule ("n if the value is at most n units and more than
//! n - 1"), confidences at 95 %, ITS time, and the map frame placed on WGS84.

use v2x_protocol::InvalidValue;

/// Two-sided 95 % factor of a normal distribution: a CPM confidence is this many stds.
pub(crate) const Z95: f64 = 1.959_963_984_540_054;

/// Unix time of the ITS epoch, 2004-01-01T00:00:00Z (ms). Leap seconds are not counted, on
/// either side.
pub(crate) const ITS_EPOCH_UNIX_MS: u64 = 1_072_915_200_000;

/// Where the map frame lies on the earth: the WGS84 latitude and longitude of its origin. The
/// frame's x axis points East, y North, z up; the map is placed on the local tangent plane,
/// which holds to the centimetre within a few kilometres of the origin.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Geo {
    /// Latitude of the map origin (degrees, -90..90).
    pub lat_deg: f64,
    /// Longitude of the map origin (degrees, -180..180).
    pub lon_deg: f64,
}

impl Geo {
    /// Metres per degree of latitude and of longitude at the origin (WGS84 series).
    fn metres_per_degree(&self) -> (f64, f64) {
        let p = self.lat_deg.to_radians();
        let lat = 111_132.954 - 559.822 * (2.0 * p).cos() + 1.175 * (4.0 * p).cos();
        let lon = 111_412.84 * p.cos() - 93.5 * (3.0 * p).cos() + 0.118 * (5.0 * p).cos();
        (lat, lon)
    }

    /// The latitude and longitude (degrees) of map point (x, y).
    pub fn to_wgs84(&self, x: f64, y: f64) -> (f64, f64) {
        let (m_lat, m_lon) = self.metres_per_degree();
        (self.lat_deg + y / m_lat, self.lon_deg + x / m_lon)
    }

    /// The map point (x, y) of a latitude and longitude (degrees).
    pub fn to_map(&self, lat_deg: f64, lon_deg: f64) -> (f64, f64) {
        let (m_lat, m_lon) = self.metres_per_degree();
        (
            (lon_deg - self.lon_deg) * m_lon,
            (lat_deg - self.lat_deg) * m_lat,
        )
    }
}

impl std::str::FromStr for Geo {
    type Err = InvalidValue;

    /// `LAT,LON` in degrees.
    fn from_str(s: &str) -> Result<Geo, InvalidValue> {
        let parts: Vec<&str> = s.split(',').collect();
        let [lat, lon] = parts.as_slice() else {
            return Err(InvalidValue::new("map origin", "LAT,LON in degrees", s));
        };
        let num = |t: &str, what: &str, max: f64| {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.abs() <= max)
                .ok_or_else(|| {
                    InvalidValue::new(what, format!("a number of degrees within +-{max}"), t)
                })
        };
        Ok(Geo {
            lat_deg: num(lat, "latitude", 90.0)?,
            lon_deg: num(lon, "longitude", 180.0)?,
        })
    }
}

/// The CPM station id of an agent: its name's stable id, a 32-bit FNV-1a hash (a CPM has no
/// names; the receiver knows the sender's name from its key expression).
pub fn station_id(agent: &str) -> u32 {
    v2x_protocol::nuscenes_json::stable_id(agent)
}

/// The code of `v` in steps of `unit` by the message's rule: n with (n - 1) unit < v <= n unit.
pub(crate) fn code(v: f64, unit: f64) -> i64 {
    (v / unit).ceil() as i64
}

/// The value a code stands for: the middle of its step, at most half a unit from the value
/// coded.
pub(crate) fn value(n: i64, unit: f64) -> f64 {
    (n as f64 - 0.5) * unit
}

/// A confidence code for `std`: the 95 % bound in steps of `unit`, at least 1, and `out_of_range`
/// above `max` (the largest code that is a value).
pub(crate) fn confidence(std: f64, unit: f64, max: i64, out_of_range: i64) -> i64 {
    let n = code(Z95 * std, unit).max(1);
    if n > max {
        out_of_range
    } else {
        n
    }
}

/// The std a confidence code stands for: its bound (the top of its step) over the 95 % factor;
/// `out_of_range` stands for the largest bound, `unavailable` for nothing.
pub(crate) fn std_of(n: i64, unit: f64, max: i64, unavailable: i64) -> Option<f64> {
    if n >= unavailable || n < 1 {
        None
    } else {
        Some(n.min(max) as f64 * unit / Z95)
    }
}
