//! Deterministic CSV: a header and rows of [`Cell`]s, floats always with [`FLOAT_DECIMALS`] decimals,
//! `\n` line ends, RFC 4180 quoting of text that needs it. The same values give the same bytes on every
//! machine. Files are written to a temp file and renamed into place, so a reader never sees half a table.
//!
//! ```no_run
//! use atlastree::report::csv::{Cell, CsvWriter};
//! let mut w = CsvWriter::create("out/summary.csv".as_ref(), &["run", "k", "mean_coarser"])?;
//! w.row(&[Cell::from("paper"), Cell::from(160u32), Cell::from(0.0125)])?;
//! w.finish()?;
//! # Ok::<(), atlastree::report::ReportError>(())
//! ```

use super::ReportError;
use crate::util::AtomicFile;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Decimals of every float cell (`{:.6}`).
pub const FLOAT_DECIMALS: usize = 6;

/// One CSV value.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    Int(i64),
    UInt(u64),
    /// Written as `{:.6}`; `-0.000000` becomes `0.000000`; NaN as `nan`, infinities as `inf` / `-inf`.
    Float(f64),
    /// Quoted when it holds a comma, a quote, CR or LF.
    Text(String),
}

impl Cell {
    /// Appends the cell's text to `out`.
    fn write_to(&self, out: &mut String) {
        use std::fmt::Write as _;
        match self {
            Cell::Int(v) => {
                let _ = write!(out, "{v}");
            }
            Cell::UInt(v) => {
                let _ = write!(out, "{v}");
            }
            Cell::Float(v) => out.push_str(&format_float(*v)),
            Cell::Text(s) => push_text(out, s),
        }
    }
}

/// The fixed float format of CSV cells (see [`Cell::Float`]).
pub fn format_float(v: f64) -> String {
    if v.is_nan() {
        return "nan".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf".into() } else { "-inf".into() };
    }
    let s = format!("{v:.FLOAT_DECIMALS$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_string(),
        _ => s,
    }
}

fn push_text(out: &mut String, s: &str) {
    if s.contains([',', '"', '\n', '\r']) {
        out.push('"');
        out.push_str(&s.replace('"', "\"\""));
        out.push('"');
    } else {
        out.push_str(s);
    }
}

macro_rules! cell_from {
    ($variant:ident, $as:ty: $($t:ty),*) => {
        $(impl From<$t> for Cell {
            fn from(v: $t) -> Cell {
                Cell::$variant(v as $as)
            }
        })*
    };
}
cell_from!(Int, i64: i8, i16, i32, i64);
cell_from!(UInt, u64: u8, u16, u32, u64, usize);
cell_from!(Float, f64: f32, f64);

impl From<&str> for Cell {
    fn from(v: &str) -> Cell {
        Cell::Text(v.to_string())
    }
}

impl From<String> for Cell {
    fn from(v: String) -> Cell {
        Cell::Text(v)
    }
}

impl From<bool> for Cell {
    /// `true` → 1, `false` → 0.
    fn from(v: bool) -> Cell {
        Cell::UInt(v as u64)
    }
}

/// One line of CSV text (with the trailing `\n`).
pub fn format_row(cells: &[Cell]) -> String {
    let mut line = String::new();
    for (i, c) in cells.iter().enumerate() {
        if i > 0 {
            line.push(',');
        }
        c.write_to(&mut line);
    }
    line.push('\n');
    line
}

/// Streams rows into a temp file beside `path`; [`CsvWriter::finish`] renames it into place. Dropped
/// without `finish` (an error on the way), the temp file is deleted and `path` is untouched.
pub struct CsvWriter {
    path: PathBuf,
    columns: usize,
    /// Data rows written so far (the header is line 1).
    rows: usize,
    out: BufWriter<AtomicFile>,
}

impl CsvWriter {
    /// Starts a table with the given header. The parent directory of `path` must exist.
    pub fn create(path: &Path, header: &[&str]) -> Result<CsvWriter, ReportError> {
        let temp = AtomicFile::create(path, 0o644).map_err(|e| ReportError::io(path, e))?;
        let mut w = CsvWriter {
            path: path.to_path_buf(),
            columns: header.len(),
            rows: 0,
            out: BufWriter::new(temp),
        };
        let header: Vec<Cell> = header.iter().map(|h| Cell::from(*h)).collect();
        w.write_line(&header)?;
        Ok(w)
    }

    /// Appends a row; it must have as many cells as the header.
    pub fn row(&mut self, cells: &[Cell]) -> Result<(), ReportError> {
        if cells.len() != self.columns {
            return Err(ReportError::Csv {
                path: self.path.clone(),
                line: self.rows + 2,
                message: format!("{} cells, header has {}", cells.len(), self.columns),
            });
        }
        self.write_line(cells)?;
        self.rows += 1;
        Ok(())
    }

    /// Data rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    fn write_line(&mut self, cells: &[Cell]) -> Result<(), ReportError> {
        self.out
            .write_all(format_row(cells).as_bytes())
            .map_err(|e| ReportError::io(&self.path, e))
    }

    /// Flushes and commits the table ([`AtomicFile::commit`]: sync, rename, directory sync); returns its
    /// path.
    pub fn finish(self) -> Result<PathBuf, ReportError> {
        let path = self.path;
        let temp = self
            .out
            .into_inner()
            .map_err(|e| ReportError::io(&path, e.into_error()))?;
        temp.commit().map_err(|e| ReportError::io(&path, e))?;
        Ok(path)
    }
}

/// Writes a whole table at once (see [`CsvWriter`]).
pub fn write_csv(path: &Path, header: &[&str], rows: &[Vec<Cell>]) -> Result<(), ReportError> {
    let mut w = CsvWriter::create(path, header)?;
    for r in rows {
        w.row(r)?;
    }
    w.finish().map(|_| ())
}

/// A parsed CSV file: the header and the rows as text.
#[derive(Clone, Debug, PartialEq)]
pub struct CsvTable {
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl CsvTable {
    /// Index of the column named `name`.
    pub fn column_index(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// The cells of column `name`, top to bottom.
    pub fn column(&self, name: &str) -> Option<Vec<&str>> {
        let i = self.column_index(name)?;
        Some(self.rows.iter().map(|r| r[i].as_str()).collect())
    }

    /// Column `name` parsed as floats (`nan`, `inf`, `-inf` included); `None` if the column is missing
    /// or a cell is not a number.
    pub fn column_f64(&self, name: &str) -> Option<Vec<f64>> {
        self.column(name)?
            .into_iter()
            .map(|s| s.parse::<f64>().ok())
            .collect()
    }
}

/// Reads a CSV file written by this module (RFC 4180 quoting, `\n` or `\r\n` line ends). Every row must
/// have as many cells as the header.
pub fn read_csv(path: &Path) -> Result<CsvTable, ReportError> {
    let text = crate::util::read_text_file(path).map_err(|e| ReportError::io(path, e))?;
    parse_csv(&text).map_err(|(line, message)| ReportError::Csv {
        path: path.to_path_buf(),
        line,
        message,
    })
}

/// Parses CSV text; errors carry the 1-based line.
fn parse_csv(text: &str) -> Result<CsvTable, (usize, String)> {
    let mut records: Vec<(usize, Vec<String>)> = Vec::new();
    let mut chars = text.chars().peekable();
    let mut line = 1;
    while chars.peek().is_some() {
        let start_line = line;
        let mut record = Vec::new();
        let mut field = String::new();
        let mut quoted = false;
        loop {
            match chars.next() {
                None => {
                    if quoted {
                        return Err((start_line, "unterminated quoted field".into()));
                    }
                    record.push(std::mem::take(&mut field));
                    break;
                }
                Some('"') if quoted => {
                    if chars.peek() == Some(&'"') {
                        chars.next();
                        field.push('"');
                    } else {
                        quoted = false;
                    }
                }
                Some('"') if field.is_empty() => quoted = true,
                Some(c) if quoted => {
                    if c == '\n' {
                        line += 1;
                    }
                    field.push(c);
                }
                Some(',') => record.push(std::mem::take(&mut field)),
                Some('\r') if chars.peek() == Some(&'\n') => {}
                Some('\n') => {
                    line += 1;
                    record.push(std::mem::take(&mut field));
                    break;
                }
                Some(c) => field.push(c),
            }
        }
        records.push((start_line, record));
    }
    let mut it = records.into_iter();
    let (_, header) = it.next().ok_or((1, "empty file: no header".to_string()))?;
    let rows = it
        .map(|(l, r)| {
            if r.len() == header.len() {
                Ok(r)
            } else {
                Err((l, format!("{} cells, header has {}", r.len(), header.len())))
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(CsvTable { header, rows })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_have_fixed_decimals_and_no_negative_zero() {
        assert_eq!(format_float(1.0), "1.000000");
        assert_eq!(format_float(-0.0), "0.000000");
        assert_eq!(format_float(-1e-9), "0.000000");
        assert_eq!(format_float(-2.5), "-2.500000");
        assert_eq!(format_float(f64::NAN), "nan");
        assert_eq!(format_float(f64::NEG_INFINITY), "-inf");
    }

    #[test]
    fn text_is_quoted_only_when_needed_and_parses_back() {
        let row = format_row(&[
            Cell::from("plain"),
            Cell::from("a,b"),
            Cell::from("say \"hi\"\nbye"),
            Cell::from(-3i32),
            Cell::from(7usize),
        ]);
        assert_eq!(row, "plain,\"a,b\",\"say \"\"hi\"\"\nbye\",-3,7\n");
        let t = parse_csv(&format!("h1,h2,h3,h4,h5\n{row}")).unwrap();
        assert_eq!(
            t.rows,
            vec![vec!["plain", "a,b", "say \"hi\"\nbye", "-3", "7"]]
        );
    }

    #[test]
    fn ragged_rows_are_rejected_with_their_line() {
        assert_eq!(parse_csv("a,b\n1,2\n3\n").unwrap_err().0, 3);
    }
}
