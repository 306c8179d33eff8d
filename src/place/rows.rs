//! Descriptor rows stored as one flat buffer with a row length.

use super::PlaceError;

/// Rows of `row_len` values each, one after the other in one `Vec`:
/// 256 floats for SuperPoint, 32 bytes for ORB or packed sign bits.
#[derive(Debug, Clone, PartialEq)]
pub struct DescriptorRows<T> {
    row_len: usize,
    data: Vec<T>,
}

impl<T: Copy> DescriptorRows<T> {
    /// No rows yet, each row `row_len` values long (> 0).
    pub fn new(row_len: usize) -> Result<Self, PlaceError> {
        Self::from_flat(row_len, Vec::new())
    }

    /// Rows taken from a flat buffer whose length is a multiple of `row_len` (> 0).
    pub fn from_flat(row_len: usize, data: Vec<T>) -> Result<Self, PlaceError> {
        if row_len == 0 {
            return Err(PlaceError::invalid(
                "row length",
                0,
                "descriptor rows need at least one value",
            ));
        }
        if !data.len().is_multiple_of(row_len) {
            return Err(PlaceError::Inconsistent {
                reason: format!(
                    "{} values are not a whole number of {row_len}-value rows",
                    data.len()
                ),
            });
        }
        Ok(Self { row_len, data })
    }

    /// Values per row.
    pub fn row_len(&self) -> usize {
        self.row_len
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.data.len() / self.row_len
    }

    /// True when there is no row.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Row `i`. Panics when `i >= len()`, like slice indexing.
    pub fn row(&self, i: usize) -> &[T] {
        &self.data[i * self.row_len..(i + 1) * self.row_len]
    }

    /// Row `i`, mutable. Panics when `i >= len()`.
    pub fn row_mut(&mut self, i: usize) -> &mut [T] {
        &mut self.data[i * self.row_len..(i + 1) * self.row_len]
    }

    /// Appends one row; its length must be the row length.
    pub fn push_row(&mut self, row: &[T]) -> Result<(), PlaceError> {
        if row.len() != self.row_len {
            return Err(PlaceError::RowLength {
                expected: self.row_len,
                actual: row.len(),
            });
        }
        self.data.extend_from_slice(row);
        Ok(())
    }

    /// Appends whole rows from a flat buffer (a multiple of the row length).
    pub fn extend_from_flat(&mut self, values: &[T]) -> Result<(), PlaceError> {
        if !values.len().is_multiple_of(self.row_len) {
            return Err(PlaceError::Inconsistent {
                reason: format!(
                    "{} values are not a whole number of {}-value rows",
                    values.len(),
                    self.row_len
                ),
            });
        }
        self.data.extend_from_slice(values);
        Ok(())
    }

    /// The rows one after the other.
    pub fn as_flat(&self) -> &[T] {
        &self.data
    }

    /// The rows in order.
    pub fn iter(&self) -> std::slice::ChunksExact<'_, T> {
        self.data.chunks_exact(self.row_len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_slices_of_the_flat_buffer() {
        let mut rows = DescriptorRows::from_flat(2, vec![1u8, 2, 3, 4]).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows.row(1), &[3, 4]);
        rows.push_row(&[5, 6]).unwrap();
        rows.row_mut(0)[1] = 9;
        assert_eq!(rows.as_flat(), &[1, 9, 3, 4, 5, 6]);
        assert_eq!(rows.iter().count(), 3);
        assert!(rows.push_row(&[1]).is_err());
        assert!(rows.extend_from_flat(&[1, 2, 3]).is_err());
        assert!(DescriptorRows::<u8>::from_flat(0, vec![]).is_err());
        assert!(DescriptorRows::from_flat(3, vec![0f32; 4]).is_err());
    }
}
