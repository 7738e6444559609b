//! Markdown tables.

use std::fmt::Write;

/// A markdown table: a header row and rows of cells.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    /// Column headers.
    pub headers: Vec<String>,
    /// Rows of cells (each as long as `headers`).
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with these headers.
    pub fn new<S: Into<String>>(headers: impl IntoIterator<Item = S>) -> Self {
        Table {
            headers: headers.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row; a short row is padded with empty cells.
    pub fn row<S: Into<String>>(&mut self, cells: impl IntoIterator<Item = S>) -> &mut Self {
        let mut r: Vec<String> = cells.into_iter().map(Into::into).collect();
        r.resize(self.headers.len().max(r.len()), String::new());
        self.rows.push(r);
        self
    }

    /// The table as GitHub-flavoured markdown, columns padded to line up.
    pub fn to_markdown(&self) -> String {
        let ncol = self.headers.len();
        let esc = |s: &str| s.replace('|', "\\|");
        let mut width: Vec<usize> = self
            .headers
            .iter()
            .map(|h| esc(h).chars().count().max(3))
            .collect();
        for r in &self.rows {
            for (j, c) in r.iter().enumerate().take(ncol) {
                width[j] = width[j].max(esc(c).chars().count());
            }
        }
        let line = |cells: &[String]| {
            let mut s = String::from("|");
            for (j, w) in width.iter().enumerate() {
                let c = cells.get(j).map(|c| esc(c)).unwrap_or_default();
                let _ = write!(s, " {c:<w$} |");
            }
            s.push('\n');
            s
        };
        let mut out = line(&self.headers);
        out.push('|');
        for w in &width {
            out.push_str(&format!(" {} |", "-".repeat(*w)));
        }
        out.push('\n');
        for r in &self.rows {
            out.push_str(&line(r));
        }
        out
    }

    /// The table as CSV (header row first), quoting cells that need it.
    pub fn to_csv(&self) -> String {
        let cell = |c: &str| {
            if c.contains([',', '"', '\n']) {
                format!("\"{}\"", c.replace('"', "\"\""))
            } else {
                c.to_string()
            }
        };
        let mut out = String::new();
        for r in std::iter::once(&self.headers).chain(self.rows.iter()) {
            let cells: Vec<String> = r.iter().map(|c| cell(c)).collect();
            out.push_str(&cells.join(","));
            out.push('\n');
        }
        out
    }
}

/// Formats a number with `digits` significant digits, switching to
/// scientific notation for very large or small magnitudes.
pub fn fmt_sig(v: f64, digits: usize) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    if v == 0.0 {
        return "0".into();
    }
    let mag = v.abs().log10().floor() as i32;
    if !(-4..6).contains(&mag) {
        return format!("{:.*e}", digits.saturating_sub(1), v);
    }
    let decimals = (digits as i32 - 1 - mag).max(0) as usize;
    format!("{v:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_and_csv() {
        let mut t = Table::new(["model", "fit %"]);
        t.row(["black-box", "81.2"]).row(["a|b, c"]);
        let md = t.to_markdown();
        assert_eq!(md.lines().count(), 4);
        assert!(
            md.starts_with("| model     | fit % |\n| --------- | ----- |\n"),
            "{md}"
        );
        assert!(md.contains("a\\|b, c"));
        let csv = t.to_csv();
        assert_eq!(csv, "model,fit %\nblack-box,81.2\n\"a|b, c\",\n");
    }

    #[test]
    fn significant_digits() {
        assert_eq!(fmt_sig(2.46913, 3), "2.47");
        assert_eq!(fmt_sig(1234.5, 3), "1234");
        assert_eq!(fmt_sig(0.012345, 3), "0.0123");
        assert_eq!(fmt_sig(1.5e-7, 2), "1.5e-7");
        assert_eq!(fmt_sig(0.0, 3), "0");
    }
}
