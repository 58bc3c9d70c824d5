//! Markdown tables: the one writer behind every table the simulator prints.

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
