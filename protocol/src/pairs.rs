//! A settings table given on one command-line flag as `KEY=VALUE,...`: the same keys, values
//! and checks as the table a scenario file gives (`link = { latency_ms = 20 }` is
//! `--link latency_ms=20`).

use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::{Map, Value};

/// `KEY=VALUE,...` read as the table `T` (its defaults for the keys left out; the empty
/// string: every default). A value is a number, `true`/`false`, or else a string.
pub fn from_pairs<T: DeserializeOwned>(s: &str) -> Result<T, String> {
    let mut map = Map::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (key, value) = part
            .split_once('=')
            .ok_or_else(|| format!("'{part}' is not KEY=VALUE"))?;
        let value = match value.trim() {
            "true" => Value::Bool(true),
            "false" => Value::Bool(false),
            v => match v.parse::<i64>() {
                Ok(i) => Value::from(i),
                Err(_) => match v.parse::<f64>() {
                    Ok(x) if x.is_finite() => Value::from(x),
                    _ => Value::String(v.to_string()),
                },
            },
        };
        if map.insert(key.trim().to_string(), value).is_some() {
            return Err(format!("'{}' is given twice", key.trim()));
        }
    }
    serde_json::from_value(Value::Object(map)).map_err(|e| e.to_string())
}

/// A table's keys with their values, `KEY=VALUE,...` as [`from_pairs`] reads them.
pub fn to_pairs<T: Serialize>(t: &T) -> String {
    match serde_json::to_value(t) {
        Ok(Value::Object(m)) => m
            .iter()
            .map(|(k, v)| match v {
                Value::String(s) => format!("{k}={s}"),
                v => format!("{k}={v}"),
            })
            .collect::<Vec<_>>()
            .join(","),
        _ => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct Table {
        count: usize,
        rate: f64,
        on: bool,
        name: String,
    }

    #[test]
    fn pairs_read_as_the_table_and_back() {
        let t: Table = from_pairs("count=3, rate=0.5,on=true,name=x").unwrap();
        let want = Table {
            count: 3,
            rate: 0.5,
            on: true,
            name: "x".into(),
        };
        assert_eq!(t, want);
        assert_eq!(from_pairs::<Table>(&to_pairs(&want)).unwrap(), want);
        assert_eq!(from_pairs::<Table>("").unwrap(), Table::default());
        // An integer where a float goes is the float.
        assert_eq!(from_pairs::<Table>("rate=2").unwrap().rate, 2.0);
    }

    #[test]
    fn each_error_names_the_key() {
        for (given, says) in [
            ("cout=3", "unknown field `cout`, expected one of `count`"),
            ("count", "'count' is not KEY=VALUE"),
            ("count=-1", "invalid value"),
            ("rate=1,rate=2", "'rate' is given twice"),
            ("rate=fast", "invalid type: string \"fast\""),
        ] {
            let e = from_pairs::<Table>(given).unwrap_err();
            assert!(e.contains(says), "{given}: {e}");
        }
    }
}
