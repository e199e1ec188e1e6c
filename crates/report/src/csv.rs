//! The few CSV files the project writes (metrics, trials, curriculum): a header line, then
//! comma-separated values without quoting.

use std::path::{Path, PathBuf};

use crate::{ReportError, Result};

/// A CSV file as read: headers and rows of cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// Where it was read.
    pub path: PathBuf,
    /// Column names.
    pub headers: Vec<String>,
    /// Rows of cells, each as long as `headers`.
    pub rows: Vec<Vec<String>>,
}

/// Reads `path`; a row with the wrong number of cells is an error naming its line.
pub fn read_table(path: &Path) -> Result<Table> {
    let text = std::fs::read_to_string(path).map_err(|source| ReportError::Io { path: path.to_path_buf(), source })?;
    parse_table(path, &text)
}

/// Parses CSV `text` read from `path`.
pub fn parse_table(path: &Path, text: &str) -> Result<Table> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let Some((_, head)) = lines.next() else {
        return Err(ReportError::Invalid { path: path.to_path_buf(), message: "empty file (no header line)".into() });
    };
    let headers: Vec<String> = head.split(',').map(|h| h.trim().to_string()).collect();
    let mut rows = Vec::new();
    for (i, line) in lines {
        let cells: Vec<String> = line.split(',').map(|c| c.trim().to_string()).collect();
        if cells.len() != headers.len() {
            return Err(ReportError::Invalid {
                path: path.to_path_buf(),
                message: format!("line {}: {} values, the header has {}", i + 1, cells.len(), headers.len()),
            });
        }
        rows.push(cells);
    }
    Ok(Table { path: path.to_path_buf(), headers, rows })
}

impl Table {
    /// Index of column `name`.
    pub fn index(&self, name: &str) -> Result<usize> {
        self.headers.iter().position(|h| h == name).ok_or_else(|| ReportError::Invalid {
            path: self.path.clone(),
            message: format!("no column `{name}` (columns: {})", self.headers.join(", ")),
        })
    }

    /// Column `name` as numbers; an empty cell or `NaN` is NaN, anything else unparsable is an
    /// error naming the line.
    pub fn column(&self, name: &str) -> Result<Vec<f64>> {
        let k = self.index(name)?;
        self.rows
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let c = r[k].as_str();
                if c.is_empty() || c.eq_ignore_ascii_case("nan") {
                    return Ok(f64::NAN);
                }
                c.parse::<f64>().map_err(|_| ReportError::Invalid {
                    path: self.path.clone(),
                    message: format!("line {}: column `{name}` holds `{c}`, not a number", i + 2),
                })
            })
            .collect()
    }

    /// Column `name` as text.
    pub fn text_column(&self, name: &str) -> Result<Vec<String>> {
        let k = self.index(name)?;
        Ok(self.rows.iter().map(|r| r[k].clone()).collect())
    }
}
