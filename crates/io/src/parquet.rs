//! Parquet files of numeric columns ([`write_parquet`]), for data sets read by Dask, Spark or pandas
//! (`simulate --fleet` writes its records with it).
//!
//! The `parquet` crate (Apache Arrow's Rust implementation of the format) with its default features
//! off: the low-level column writer only — no Arrow arrays, no compression codecs — which adds about 40 s
//! to a clean debug build. Columns are written uncompressed (PLAIN/dictionary encodings as the crate
//! chooses), which every Parquet reader (pyarrow, Spark, DuckDB) reads.

use std::path::Path;
use std::sync::Arc;

use parquet::data_type::{DoubleType, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;

use crate::OutputError;

/// One column of a Parquet table.
#[derive(Debug, Clone, Copy)]
pub enum Column<'a> {
    /// 64-bit integers (an identifier).
    Int64(&'a str, &'a [i64]),
    /// 64-bit floats.
    Double(&'a str, &'a [f64]),
}

impl Column<'_> {
    fn name(&self) -> &str {
        match self {
            Column::Int64(n, _) | Column::Double(n, _) => n,
        }
    }
    fn len(&self) -> usize {
        match self {
            Column::Int64(_, v) => v.len(),
            Column::Double(_, v) => v.len(),
        }
    }
}

/// The bytes of a Parquet file holding `columns` (all of one length, required values) as one row group.
pub fn parquet_bytes(columns: &[Column<'_>]) -> Result<Vec<u8>, String> {
    let rows = columns.first().map_or(0, Column::len);
    if let Some(c) = columns.iter().find(|c| c.len() != rows) {
        return Err(format!(
            "column {} has {} values, the first {rows}",
            c.name(),
            c.len()
        ));
    }
    let fields = columns
        .iter()
        .map(|c| {
            let physical = match c {
                Column::Int64(..) => parquet::basic::Type::INT64,
                Column::Double(..) => parquet::basic::Type::DOUBLE,
            };
            Type::primitive_type_builder(c.name(), physical)
                .with_repetition(parquet::basic::Repetition::REQUIRED)
                .build()
                .map(Arc::new)
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())?;
    let schema = Type::group_type_builder("schema")
        .with_fields(fields)
        .build()
        .map_err(|e| e.to_string())?;
    let props = Arc::new(WriterProperties::builder().build());
    let mut out = Vec::new();
    let mut writer =
        SerializedFileWriter::new(&mut out, Arc::new(schema), props).map_err(|e| e.to_string())?;
    let mut group = writer.next_row_group().map_err(|e| e.to_string())?;
    for c in columns {
        let Some(mut w) = group.next_column().map_err(|e| e.to_string())? else {
            return Err("the schema has fewer columns than given".into());
        };
        match c {
            Column::Int64(_, v) => w.typed::<Int64Type>().write_batch(v, None, None),
            Column::Double(_, v) => w.typed::<DoubleType>().write_batch(v, None, None),
        }
        .map_err(|e| e.to_string())?;
        w.close().map_err(|e| e.to_string())?;
    }
    group.close().map_err(|e| e.to_string())?;
    writer.close().map_err(|e| e.to_string())?;
    Ok(out)
}

/// Writes `columns` as a Parquet file at `path`, atomically ([`crate::write_atomic`]).
pub fn write_parquet(path: &Path, columns: &[Column<'_>]) -> Result<(), OutputError> {
    let bytes = parquet_bytes(columns).map_err(|e| OutputError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    })?;
    crate::write_atomic(path, &bytes)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::Field;

    // What is written is read back, value for value, by the crate's own reader.
    #[test]
    fn columns_round_trip() {
        let ids = [7_i64, 7, 9];
        let y = [0.1, -2.5e-300, f64::MAX];
        let bytes =
            parquet_bytes(&[Column::Int64("actuator_id", &ids), Column::Double("y", &y)]).unwrap();
        assert_eq!(&bytes[..4], b"PAR1");
        let reader = SerializedFileReader::new(bytes::Bytes::from(bytes)).unwrap();
        let rows: Vec<(i64, f64)> = reader
            .get_row_iter(None)
            .unwrap()
            .map(|r| {
                let r = r.unwrap();
                let mut it = r.get_column_iter();
                let (Field::Long(a), Field::Double(b)) =
                    (it.next().unwrap().1.clone(), it.next().unwrap().1.clone())
                else {
                    panic!("unexpected types")
                };
                (a, b)
            })
            .collect();
        assert_eq!(rows, vec![(7, 0.1), (7, -2.5e-300), (9, f64::MAX)]);
    }

    #[test]
    fn columns_of_different_lengths_are_refused() {
        let e = parquet_bytes(&[Column::Int64("a", &[1]), Column::Double("b", &[])]).unwrap_err();
        assert!(e.contains("column b"), "{e}");
    }
}
