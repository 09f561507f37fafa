//! CSV tables: every CSV file and listing the command line writes is built here, through the
//! `csv` crate (a field is quoted only where it needs it: a comma, quote or line break, RFC
//! 4180), so that a response or variable named with a comma cannot shift the columns.

/// A CSV table built row by row in memory (the callers write it atomically).
pub(crate) struct CsvTable(csv::Writer<Vec<u8>>);

impl CsvTable {
    /// An empty table; rows may have different lengths.
    pub(crate) fn new() -> Self {
        Self(
            csv::WriterBuilder::new()
                .flexible(true)
                .from_writer(Vec::new()),
        )
    }

    /// Append one row.
    pub(crate) fn row<I, F>(&mut self, fields: I)
    where
        I: IntoIterator<Item = F>,
        F: AsRef<str>,
    {
        self.0
            .write_record(fields.into_iter().map(|f| f.as_ref().to_owned()))
            .expect("writing CSV to memory cannot fail");
    }

    /// The table's text.
    pub(crate) fn finish(self) -> String {
        let bytes = self
            .0
            .into_inner()
            .map_err(|e| e.to_string())
            .expect("flushing CSV to memory cannot fail");
        String::from_utf8(bytes).expect("CSV of UTF-8 fields is UTF-8")
    }
}

/// A number printed as short as it reads (`1e-4`, `0.0001`), 6 significant digits.
pub(crate) fn short(x: f64) -> String {
    let r: f64 = format!("{x:.5e}").parse().unwrap_or(x);
    format!("{r}")
}

/// `x` in the tables' number format (shortest round-trip exponent form, e.g. `1.5e-3`).
pub(crate) fn number(x: f64) -> String {
    format!("{x:e}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_quoted_only_where_they_need_it() {
        let mut t = CsvTable::new();
        t.row(["time [s]", "a, b [m]", "say \"hi\"", ""]);
        t.row([number(1.5e-3), number(0.0)]);
        assert_eq!(
            t.finish(),
            "time [s],\"a, b [m]\",\"say \"\"hi\"\"\",\n1.5e-3,0e0\n"
        );
    }
}
