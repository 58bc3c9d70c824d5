//! Tables: the one writer behind every table the simulator prints ([`markdown`]), and the one
//! printer of a bench's rows in every format ([`Rows`], [`render`]).

/// How a column's cells align: text to the left, figures to the right.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Align {
    /// Text.
    Left,
    /// Figures.
    Right,
}

/// A Markdown table with these columns (heading, alignment) and rows of cells.
pub fn markdown<R: IntoIterator<Item = String>>(
    columns: &[(&str, Align)],
    rows: impl IntoIterator<Item = R>,
) -> String {
    let mut s = String::new();
    line(&mut s, columns.iter().map(|c| c.0.to_string()));
    s.push('|');
    for (_, align) in columns {
        s.push_str(match align {
            Align::Left => "---|",
            Align::Right => "---:|",
        });
    }
    s.push('\n');
    for r in rows {
        line(&mut s, r);
    }
    s
}

/// Appends one row: `| a | b |` and a new line.
fn line(s: &mut String, cells: impl IntoIterator<Item = String>) {
    s.push('|');
    for c in cells {
        s.push(' ');
        s.push_str(&c);
        s.push_str(" |");
    }
    s.push('\n');
}

/// How rows are printed.
#[derive(Copy, Clone, Debug, clap::ValueEnum, PartialEq, Eq)]
pub enum Format {
    /// A Markdown table after a line that says what was run.
    Table,
    /// The rows as JSON.
    Json,
    /// The rows as CSV, where they have a CSV form (else the table).
    Csv,
}

/// A bench's rows, in every form they print as.
pub trait Rows: serde::Serialize {
    /// The rows as a Markdown table.
    fn table(&self) -> String;
    /// The rows as CSV; `None` when they have no CSV form.
    fn csv(&self) -> Option<String> {
        None
    }
}

/// The one printer of rows: as JSON, as CSV, or as a table after `heading` and a blank line.
pub fn render<R: Rows + ?Sized>(
    rows: &R,
    format: Format,
    heading: &str,
) -> serde_json::Result<String> {
    Ok(match (format, rows.csv()) {
        (Format::Json, _) => serde_json::to_string_pretty(rows)? + "\n",
        (Format::Csv, Some(csv)) => csv,
        _ => format!("{heading}\n\n{}", rows.table()),
    })
}

/// A cell: the value with `digits` decimals, or `-` when there is none.
pub fn cell(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "-".to_string(), |x| format!("{x:.digits$}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_align_and_missing_figures_show_as_a_dash() {
        let t = markdown(
            &[("method", Align::Left), ("mATE (m)", Align::Right)],
            [
                vec!["a".to_string(), cell(Some(0.12345), 3)],
                vec!["b".to_string(), cell(None, 3)],
            ],
        );
        assert_eq!(
            t,
            "| method | mATE (m) |\n|---|---:|\n| a | 0.123 |\n| b | - |\n"
        );
    }
}
