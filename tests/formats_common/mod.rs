//! Writers of the binary data formats for the tests (`tests/formats.rs`,
//! `tests/bad_inputs.rs`): MAT v5 by a minimal writer here (the layout of the MAT-file
//! format description: 128-byte header, tagged elements, small elements for data of up to
//! 4 bytes as MATLAB writes short names, zlib-compressed elements); HDF5, MAT v7.3 and
//! Parquet by the writers of the crates that read them (`hdf5-pure`, `parquet`).
#![allow(dead_code)] // each test binary uses a subset

use std::io::Write;
use std::path::Path;

/// A CSV file's header and columns (the `t` column included), parsed here.
pub fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let names: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut cols = vec![Vec::new(); names.len()];
    for l in lines.filter(|l| !l.trim().is_empty()) {
        for (c, f) in cols.iter_mut().zip(l.split(',')) {
            c.push(f.trim().parse::<f64>().unwrap());
        }
    }
    (names, cols)
}

// ---- MAT v5 ------------------------------------------------------------------------------

/// One tagged element: small format for 1 to 4 bytes (as MATLAB writes short names), else
/// tag, data and padding to 8 bytes.
pub fn element(mi: u32, data: &[u8]) -> Vec<u8> {
    let mut v = Vec::new();
    if !data.is_empty() && data.len() <= 4 {
        v.extend_from_slice(&(((data.len() as u32) << 16) | mi).to_le_bytes());
        v.extend_from_slice(data);
        v.resize(8, 0);
        return v;
    }
    v.extend_from_slice(&mi.to_le_bytes());
    v.extend_from_slice(&(data.len() as u32).to_le_bytes());
    v.extend_from_slice(data);
    v.resize(v.len().div_ceil(8) * 8, 0);
    v
}

/// A matrix element: class, dimensions, name, then `body` (the data elements).
pub fn matrix(class: u8, dims: &[usize], name: &str, body: &[u8]) -> Vec<u8> {
    let mut m = element(6, &[&(class as u32).to_le_bytes()[..], &[0; 4]].concat());
    let d: Vec<u8> = dims
        .iter()
        .flat_map(|&x| (x as i32).to_le_bytes())
        .collect();
    m.extend(element(5, &d));
    m.extend(element(1, name.as_bytes()));
    m.extend_from_slice(body);
    element(14, &m)
}

pub fn doubles(v: &[f64]) -> Vec<u8> {
    element(
        9,
        &v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>(),
    )
}

pub fn char_row(s: &str) -> Vec<u8> {
    let units: Vec<u8> = s.encode_utf16().flat_map(|u| u.to_le_bytes()).collect();
    matrix(4, &[1, s.len()], "", &element(4, &units))
}

pub fn mat5_file(elements: &[Vec<u8>], compress: bool) -> Vec<u8> {
    let mut f = format!("MATLAB 5.0 MAT-file, written by tests/formats.rs{:68}", "").into_bytes();
    f.truncate(116);
    f.extend_from_slice(&[0; 8]);
    f.extend_from_slice(&[0x00, 0x01]);
    f.extend_from_slice(b"IM");
    for e in elements {
        if compress {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(e).unwrap();
            let z = z.finish().unwrap();
            f.extend_from_slice(&15u32.to_le_bytes());
            f.extend_from_slice(&(z.len() as u32).to_le_bytes());
            f.extend_from_slice(&z);
        } else {
            f.extend_from_slice(e);
        }
    }
    f
}

/// One column vector (`N×1` double) per signal.
pub fn mat5_vectors(names: &[String], cols: &[Vec<f64>], compress: bool) -> Vec<u8> {
    let els: Vec<Vec<u8>> = names
        .iter()
        .zip(cols)
        .map(|(n, c)| matrix(6, &[c.len(), 1], n, &doubles(c)))
        .collect();
    mat5_file(&els, compress)
}

/// One `N×k` matrix `data` and a cell array `names` of char rows (with a stray scalar).
pub fn mat5_matrix(names: &[String], cols: &[Vec<f64>]) -> Vec<u8> {
    let n = cols[0].len();
    let flat: Vec<f64> = cols.iter().flatten().copied().collect();
    let data = matrix(6, &[n, cols.len()], "data", &doubles(&flat));
    let cells: Vec<u8> = names.iter().flat_map(|s| char_row(s)).collect();
    let names_el = matrix(1, &[1, names.len()], "names", &cells);
    let gain = matrix(6, &[1, 1], "gain", &doubles(&[2.5]));
    mat5_file(&[gain, data, names_el], true)
}

// ---- MAT v7.3 and HDF5 -------------------------------------------------------------------

pub fn mat73_vectors(names: &[String], cols: &[Vec<f64>]) -> Vec<u8> {
    let mut b = hdf5_pure::mat::MatBuilder::new(Default::default());
    for (n, c) in names.iter().zip(cols) {
        b.write_f64(n, &[c.len(), 1], c).unwrap();
    }
    b.finish().unwrap()
}

pub fn mat73_matrix(names: &[String], cols: &[Vec<f64>]) -> Vec<u8> {
    let mut b = hdf5_pure::mat::MatBuilder::new(Default::default());
    let flat: Vec<f64> = cols.iter().flatten().copied().collect();
    b.write_f64("data", &[cols[0].len(), cols.len()], &flat)
        .unwrap();
    b.write_char("names", &names.join(",")).unwrap();
    b.finish().unwrap()
}

/// As [`mat73_matrix`], with `names` a cell array of char vectors (`names = {'t', ...}`).
pub fn mat73_matrix_cell(names: &[String], cols: &[Vec<f64>]) -> Vec<u8> {
    let mut b = hdf5_pure::mat::MatBuilder::new(Default::default());
    let flat: Vec<f64> = cols.iter().flatten().copied().collect();
    b.write_f64("data", &[cols[0].len(), cols.len()], &flat)
        .unwrap();
    b.cell("names", &[1, names.len()], |c| {
        for n in names {
            c.push_char(n)?;
        }
        Ok(())
    })
    .unwrap();
    b.finish().unwrap()
}

/// 1-D datasets, chunked (1000 samples, so windows cross chunks) and deflated.
pub fn h5_vectors(names: &[String], cols: &[Vec<f64>]) -> Vec<u8> {
    let mut b = hdf5_pure::FileBuilder::new();
    for (n, c) in names.iter().zip(cols) {
        b.create_dataset(n)
            .with_f64_data(c)
            .with_shape(&[c.len() as u64])
            .with_chunks(&[1000])
            .with_deflate(4);
    }
    b.finish().unwrap()
}

/// One `[N, k]` dataset (a sample per row, as NumPy writes a table) and string names.
pub fn h5_matrix(names: &[String], cols: &[Vec<f64>]) -> Vec<u8> {
    let n = cols[0].len();
    let rows: Vec<f64> = (0..n)
        .flat_map(|i| cols.iter().map(move |c| c[i]))
        .collect();
    let mut b = hdf5_pure::FileBuilder::new();
    b.create_dataset("data")
        .with_f64_data(&rows)
        .with_shape(&[n as u64, cols.len() as u64]);
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    b.create_dataset("names").with_vlen_strings(&refs);
    b.finish().unwrap()
}

// ---- Parquet -----------------------------------------------------------------------------

/// A Parquet schema of one DOUBLE column per name, all with `repetition`.
fn parquet_schema(
    names: &[String],
    repetition: parquet::basic::Repetition,
) -> std::sync::Arc<parquet::schema::types::Type> {
    use parquet::basic::Type as Physical;
    use parquet::schema::types::Type;
    use std::sync::Arc;
    let fields = names
        .iter()
        .map(|n| {
            Arc::new(
                Type::primitive_type_builder(n, Physical::DOUBLE)
                    .with_repetition(repetition)
                    .build()
                    .unwrap(),
            )
        })
        .collect();
    Arc::new(
        Type::group_type_builder("record")
            .with_fields(fields)
            .build()
            .unwrap(),
    )
}

/// Required DOUBLE columns, Snappy pages, in two row groups.
pub fn parquet_file(names: &[String], cols: &[Vec<f64>], path: &Path) {
    parquet_file_compressed(names, cols, path, parquet::basic::Compression::SNAPPY)
}

/// As [`parquet_file`], pages compressed with `compression`.
pub fn parquet_file_compressed(
    names: &[String],
    cols: &[Vec<f64>],
    path: &Path,
    compression: parquet::basic::Compression,
) {
    use parquet::basic::Repetition;
    use parquet::file::properties::WriterProperties;
    use parquet::file::writer::SerializedFileWriter;
    use std::sync::Arc;
    let schema = parquet_schema(names, Repetition::REQUIRED);
    let props = Arc::new(
        WriterProperties::builder()
            .set_compression(compression)
            .build(),
    );
    let file = std::fs::File::create(path).unwrap();
    let mut w = SerializedFileWriter::new(file, schema, props).unwrap();
    let n = cols[0].len();
    for range in [0..n / 3, n / 3..n] {
        let mut rg = w.next_row_group().unwrap();
        for c in cols {
            let mut cw = rg.next_column().unwrap().unwrap();
            cw.typed::<parquet::data_type::DoubleType>()
                .write_batch(&c[range.clone()], None, None)
                .unwrap();
            cw.close().unwrap();
        }
        rg.close().unwrap();
    }
    w.close().unwrap();
}

/// One OPTIONAL DOUBLE column per signal, with no value (a null) at sample `null_at` of
/// the column `null_in`.
pub fn parquet_with_null(
    names: &[String],
    cols: &[Vec<f64>],
    null_in: usize,
    null_at: usize,
    path: &Path,
) {
    use parquet::basic::Repetition;
    use parquet::file::properties::WriterProperties;
    use parquet::file::writer::SerializedFileWriter;
    use std::sync::Arc;
    let schema = parquet_schema(names, Repetition::OPTIONAL);
    let props = Arc::new(WriterProperties::builder().build());
    let file = std::fs::File::create(path).unwrap();
    let mut w = SerializedFileWriter::new(file, schema, props).unwrap();
    let mut rg = w.next_row_group().unwrap();
    for (k, c) in cols.iter().enumerate() {
        let mut cw = rg.next_column().unwrap().unwrap();
        let defs: Vec<i16> = (0..c.len())
            .map(|i| i16::from(!(k == null_in && i == null_at)))
            .collect();
        let vals: Vec<f64> = c
            .iter()
            .enumerate()
            .filter(|(i, _)| defs[*i] == 1)
            .map(|(_, v)| *v)
            .collect();
        cw.typed::<parquet::data_type::DoubleType>()
            .write_batch(&vals, Some(&defs), None)
            .unwrap();
        cw.close().unwrap();
    }
    rg.close().unwrap();
    w.close().unwrap();
}
