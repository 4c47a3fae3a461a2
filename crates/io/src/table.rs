//! A small strict CSV table: header checked against the allowed columns, rows checked for
//! their field count, typed accessors whose errors name the file, the line and the field.

use super::InputError;
use csv::StringRecord;
use std::io::Read;
use std::path::{Path, PathBuf};

/// A parsed CSV file: its header and its data rows with their 1-based line numbers.
///
/// The (trimmed) fields of every data row are stored back to back in one string, so that a
/// file of a hundred thousand rows costs a few allocations, not three per row.
pub struct Table {
    pub path: PathBuf,
    pub header_line: u64,
    columns: Vec<String>,
    /// Every data field, concatenated in file order.
    text: String,
    /// Byte range of each data field in `text`, in file order.
    fields: Vec<(usize, usize)>,
    /// Each data row: its line, and the range of its fields in `fields`.
    rows: Vec<(u64, usize, usize)>,
}

impl Table {
    /// Reads a whole CSV source. `allowed` lists every column name the file may have;
    /// `expected` is the header shown in the error for an empty file.
    pub fn read<R: Read>(
        path: &Path,
        reader: R,
        allowed: &[&str],
        expected: &str,
    ) -> Result<Self, InputError> {
        let mut bytes = Vec::new();
        let mut reader = reader;
        reader
            .read_to_end(&mut bytes)
            .map_err(|source| InputError::Read {
                path: path.to_path_buf(),
                source,
            })?;
        // Line numbers are counted here from the byte offsets: the csv crate's own line
        // counter skips comment lines, and its offsets point before skipped blank lines.
        // Newline offsets, so that a line number costs a binary search (not a rescan).
        let newlines: Vec<usize> = bytes
            .iter()
            .enumerate()
            .filter_map(|(i, &b)| (b == b'\n').then_some(i))
            .collect();
        let line_of = |byte: u64| -> u64 {
            let mut start = usize::try_from(byte).unwrap_or(usize::MAX).min(bytes.len());
            while start < bytes.len() {
                match bytes[start] {
                    b'\n' | b'\r' => start += 1,
                    b'#' => {
                        while start < bytes.len() && bytes[start] != b'\n' {
                            start += 1;
                        }
                    }
                    _ => break,
                }
            }
            1 + newlines.partition_point(|&i| i < start) as u64
        };
        let mut csv_reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            // Fields are trimmed below (`str::trim`, as `csv::Trim::All` does, but without
            // the csv crate's copy of every record).
            .trim(csv::Trim::None)
            .comment(Some(b'#'))
            .from_reader(bytes.as_slice());
        // One record buffer reused for every row (the same parsing, trimming and UTF-8
        // checks as `records()`, without an allocation per row).
        let mut record = StringRecord::new();
        let mut next_record = |record: &mut StringRecord| -> Result<Option<u64>, InputError> {
            match csv_reader.read_record(record) {
                Ok(true) => Ok(Some(record.position().map_or(0, |p| line_of(p.byte())))),
                Ok(false) => Ok(None),
                Err(e) => Err(csv_error(path, &e, &line_of)),
            }
        };
        let Some(header_line) = next_record(&mut record)? else {
            return Err(InputError::field(
                path,
                1,
                "header",
                format!("the file is empty (expected a header line `{expected}`)"),
            ));
        };
        // Every record is read before the header is checked (a CSV error anywhere in the
        // file is reported first, as when the records were collected at once).
        let header: Vec<String> = record.iter().map(|f| f.trim().to_string()).collect();
        let mut text = String::with_capacity(bytes.len());
        let mut fields = Vec::with_capacity(newlines.len() * header.len());
        let mut rows = Vec::with_capacity(newlines.len());
        while let Some(line) = next_record(&mut record)? {
            let first = fields.len();
            for field in &record {
                let start = text.len();
                text.push_str(field.trim());
                fields.push((start, text.len()));
            }
            rows.push((line, first, fields.len()));
        }
        let mut columns: Vec<String> = Vec::with_capacity(header.len());
        for (k, name) in header.iter().map(String::as_str).enumerate() {
            if name.is_empty() {
                return Err(InputError::field(
                    path,
                    header_line,
                    format!("column {}", k + 1),
                    format!("empty column name in the header (expected `{expected}`)"),
                ));
            }
            if !allowed.contains(&name) {
                return Err(InputError::field(
                    path,
                    header_line,
                    name,
                    format!(
                        "unknown column (allowed columns: {}; expected header `{expected}`)",
                        allowed.join(", ")
                    ),
                ));
            }
            if columns.iter().any(|c| c == name) {
                return Err(InputError::field(
                    path,
                    header_line,
                    name,
                    "column appears twice in the header",
                ));
            }
            columns.push(name.to_string());
        }
        Ok(Self {
            path: path.to_path_buf(),
            header_line,
            columns,
            text,
            fields,
            rows,
        })
    }

    /// The number of data rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when the file has no data row.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// True when the header has this column.
    pub fn has(&self, column: &str) -> bool {
        self.columns.iter().any(|c| c == column)
    }

    /// Errors unless the header has every one of `columns`.
    pub fn require(&self, columns: &[&str], expected: &str) -> Result<(), InputError> {
        for column in columns {
            if !self.has(column) {
                return Err(self.header_error(
                    column,
                    format!("required column is missing from the header (expected `{expected}`)"),
                ));
            }
        }
        Ok(())
    }

    /// An error about the header.
    pub fn header_error(&self, field: &str, reason: impl Into<String>) -> InputError {
        InputError::field(&self.path, self.header_line, field, reason)
    }

    /// The data rows in file order, each checked for its field count.
    pub fn rows(&self) -> impl Iterator<Item = Result<Row<'_>, InputError>> {
        self.rows.iter().map(move |&(line, first, end)| {
            let fields = &self.fields[first..end];
            let (n, m) = (fields.len(), self.columns.len());
            if n < m {
                return Err(InputError::field(
                    &self.path,
                    line,
                    &self.columns[n],
                    format!("missing value: the row has {n} fields, the header has {m}"),
                ));
            }
            if n > m {
                let (a, b) = fields[m];
                return Err(InputError::field(
                    &self.path,
                    line,
                    format!("column {}", m + 1),
                    format!(
                        "unexpected extra value `{}`: the row has {n} fields, the header has {m}",
                        &self.text[a..b]
                    ),
                ));
            }
            Ok(Row {
                table: self,
                line,
                fields,
            })
        })
    }
}

/// One data row of a [`Table`].
pub struct Row<'a> {
    table: &'a Table,
    pub line: u64,
    /// Byte ranges of the row's fields in the table's text.
    fields: &'a [(usize, usize)],
}

impl Row<'_> {
    /// An error about a field of this row.
    pub fn error(&self, field: &str, reason: impl Into<String>) -> InputError {
        InputError::field(&self.table.path, self.line, field, reason)
    }

    /// The trimmed text of a column, or `None` when the header lacks the column.
    pub fn raw(&self, column: &str) -> Option<&str> {
        let k = self.table.columns.iter().position(|c| c == column)?;
        let &(a, b) = self.fields.get(k)?;
        self.table.text.get(a..b)
    }

    /// A non-empty text value of an optional column (`None` when absent or empty).
    pub fn optional_str(&self, column: &str) -> Option<&str> {
        self.raw(column).filter(|s| !s.is_empty())
    }

    /// A non-empty text value of a required column.
    pub fn required_str(&self, column: &str) -> Result<&str, InputError> {
        self.optional_str(column)
            .ok_or_else(|| self.error(column, "missing value"))
    }

    /// A finite number of an optional column (`None` when absent or empty).
    pub fn optional_f64(&self, column: &str) -> Result<Option<f64>, InputError> {
        match self.optional_str(column) {
            None => Ok(None),
            Some(text) => {
                let value: f64 = text
                    .parse()
                    .map_err(|_| self.error(column, format!("`{text}` is not a number")))?;
                if !value.is_finite() {
                    return Err(self.error(column, format!("`{text}` is not a finite number")));
                }
                Ok(Some(value))
            }
        }
    }

    /// A finite number of a required column.
    pub fn required_f64(&self, column: &str) -> Result<f64, InputError> {
        self.optional_f64(column)?
            .ok_or_else(|| self.error(column, "missing value"))
    }
}

/// Converts a CSV decoding error (invalid UTF-8, I/O) into an [`InputError`].
fn csv_error(path: &Path, error: &csv::Error, line_of: &dyn Fn(u64) -> u64) -> InputError {
    match error.kind() {
        csv::ErrorKind::Io(e) => InputError::Read {
            path: path.to_path_buf(),
            source: std::io::Error::new(e.kind(), e.to_string()),
        },
        csv::ErrorKind::Utf8 { pos, err } => InputError::field(
            path,
            pos.as_ref().map_or(0, |p| line_of(p.byte())),
            format!("column {}", err.field() + 1),
            "the value is not valid UTF-8",
        ),
        _ => InputError::field(
            path,
            error.position().map_or(0, |p| line_of(p.byte())),
            "record",
            error.to_string(),
        ),
    }
}

/// Opens a file for one of the readers, mapping failure to [`InputError::Read`].
pub fn open(path: &Path) -> Result<std::fs::File, InputError> {
    std::fs::File::open(path).map_err(|source| InputError::Read {
        path: path.to_path_buf(),
        source,
    })
}
