//! Reading the CSV files loam takes (a body's `velocity_file`, an inversion's observations)
//! as spreadsheets save them.

use std::path::Path;

/// The byte-order mark U+FEFF that spreadsheet programs put at the start of a CSV file they
/// save as "UTF-8".
const BOM: char = '\u{feff}';

/// Reads the text of the CSV file `path`, without the byte-order mark a spreadsheet may put
/// before the header (it would otherwise be part of the first column's name).
///
/// # Errors
/// The file cannot be read or is not UTF-8.
pub fn read_csv(path: &Path) -> std::io::Result<String> {
    let text = std::fs::read_to_string(path)?;
    Ok(match text.strip_prefix(BOM) {
        Some(rest) => rest.to_owned(),
        None => text,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_byte_order_mark_is_dropped_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("v.csv");
        std::fs::write(&file, "\u{feff}vx, vy\r\n1, 2\r\n").unwrap();
        assert_eq!(read_csv(&file).unwrap(), "vx, vy\r\n1, 2\r\n");
        std::fs::write(&file, "vx, vy\n").unwrap();
        assert_eq!(read_csv(&file).unwrap(), "vx, vy\n");
    }
}
