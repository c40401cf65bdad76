//! [`Buffer`]: a read-only array that either owns its elements or views a section of a
//! memory-mapped brick cache file (`crate::cache`).
//!
//! The volume's hot loops index `&[T]`; whether those elements live on the heap or in
//! the page cache is decided once, when the volume is built or opened. A mapped buffer
//! keeps its mapping alive through an `Arc`, so a [`Buffer`] is `'static` data and the
//! volume can be shared across render threads like an in-core one. Mapped pages are file
//! pages: the kernel pages them in on first touch and may drop them under pressure, and
//! they never count as the process's anonymous memory.

use std::ops::Deref;
use std::sync::Arc;

use bytemuck::Pod;

use crate::out_of_core::mapfault::Mapping;

/// Who keeps a [`Buffer`]'s elements alive.
#[derive(Debug)]
enum Owner<T> {
    Heap(Vec<T>),
    Map(#[allow(dead_code)] Arc<Mapping>),
}

/// A read-only `[T]` on the heap or in a mapped file. See the module docs.
#[derive(Debug)]
pub struct Buffer<T: Pod> {
    ptr: *const T,
    len: usize,
    owner: Owner<T>,
}

// SAFETY: a Buffer is an immutable view. Heap elements are owned and never mutated after
// construction; a mapping is read-only (`Mmap`, not `MmapMut`) and `Arc`-shared. `T: Pod`
// holds no pointers or interior mutability, so sharing `&[T]` across threads is sound.
unsafe impl<T: Pod + Sync> Send for Buffer<T> {}
// SAFETY: see `Send`.
unsafe impl<T: Pod + Sync> Sync for Buffer<T> {}

impl<T: Pod> Buffer<T> {
    /// A heap buffer that owns `values`.
    #[must_use]
    pub fn from_vec(values: Vec<T>) -> Buffer<T> {
        Buffer { ptr: values.as_ptr(), len: values.len(), owner: Owner::Heap(values) }
    }

    /// A view of `bytes` (a range of `map`) as `[T]`.
    ///
    /// Returns `None` when the range lies outside the mapping, is not a whole number of
    /// `T`s, or is not aligned for `T` (cache sections are page-aligned).
    #[must_use]
    pub fn mapped(map: &Arc<Mapping>, offset: usize, bytes: usize) -> Option<Buffer<T>> {
        let end = offset.checked_add(bytes)?;
        let slice: &[u8] = map.get(offset..end)?;
        let typed: &[T] = bytemuck::try_cast_slice(slice).ok()?;
        Some(Buffer { ptr: typed.as_ptr(), len: typed.len(), owner: Owner::Map(Arc::clone(map)) })
    }

    /// True when the elements live in a mapped file.
    #[must_use]
    pub fn is_mapped(&self) -> bool {
        matches!(self.owner, Owner::Map(_))
    }

    /// Heap bytes held (0 for a mapped buffer).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        match &self.owner {
            Owner::Heap(v) => v.capacity() * std::mem::size_of::<T>(),
            Owner::Map(_) => 0,
        }
    }

    /// Bytes viewed, wherever they live.
    #[must_use]
    pub fn byte_len(&self) -> usize {
        self.len * std::mem::size_of::<T>()
    }
}

impl<T: Pod> Buffer<T> {
    /// Ask the OS to start reading the elements in `ranges` (ascending, in bounds) from
    /// the file, without waiting (`madvise(MADV_WILLNEED)`). A hint: nothing for a heap
    /// buffer, and failures are ignored; what is read never changes.
    pub fn will_need(&self, ranges: impl Iterator<Item = std::ops::Range<usize>>) {
        let Owner::Map(map) = &self.owner else { return };
        let size = std::mem::size_of::<T>();
        // Offset of element 0 in the mapping (the buffer is a checked range of it)
        let base = self.ptr as usize - map.as_ptr() as usize;
        for r in ranges {
            let (start, end) = (r.start.min(self.len), r.end.min(self.len));
            if start < end {
                let _ = map.advise_range(
                    memmap2::Advice::WillNeed,
                    base + start * size,
                    (end - start) * size,
                );
            }
        }
    }

    /// Tell the OS that page faults on this buffer come at random (`MADV_RANDOM`): a fault
    /// then reads its page, not the read-around window (`read_ahead_kb`, up to megabytes),
    /// for a reader that asks for what it needs with [`Buffer::will_need`]. A hint:
    /// nothing for a heap buffer.
    pub fn fault_pages_only(&self) {
        let Owner::Map(map) = &self.owner else { return };
        if self.len > 0 {
            let base = self.ptr as usize - map.as_ptr() as usize;
            let _ = map.advise_range(memmap2::Advice::Random, base, self.byte_len());
        }
    }
}

impl<T: Pod> Default for Buffer<T> {
    fn default() -> Self {
        Buffer::from_vec(Vec::new())
    }
}

impl<T: Pod> Deref for Buffer<T> {
    type Target = [T];

    #[inline]
    fn deref(&self) -> &[T] {
        // SAFETY: `ptr`/`len` describe either the owned Vec (which is never resized after
        // construction and moves with `owner` without moving its heap block) or a checked,
        // aligned range of a read-only mapping kept alive by `owner`.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

impl<T: Pod> From<Vec<T>> for Buffer<T> {
    fn from(v: Vec<T>) -> Self {
        Buffer::from_vec(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn heap_and_mapped_buffers_read_the_same_values() {
        let values: Vec<f32> = (0..4096).map(|i| i as f32 * 0.5).collect();
        let heap = Buffer::from_vec(values.clone());
        assert_eq!(&heap[..], &values[..]);
        assert!(!heap.is_mapped());

        let path = std::env::temp_dir().join(format!("plume-storage-test-{}", std::process::id()));
        let mut file = std::fs::File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .unwrap();
        std::fs::remove_file(&path).unwrap();
        file.write_all(&[0u8; 4096]).unwrap();
        file.write_all(bytemuck::cast_slice(&values)).unwrap();
        let map = Arc::new(Mapping::map(&file, &path, "test file").unwrap());
        let mapped = Buffer::<f32>::mapped(&map, 4096, values.len() * 4).unwrap();
        assert_eq!(&mapped[..], &values[..]);
        assert!(mapped.is_mapped());
        assert_eq!(mapped.heap_bytes(), 0);
        // Out of range, misaligned and ragged views are refused
        assert!(Buffer::<f32>::mapped(&map, 4096, values.len() * 4 + 4).is_none());
        assert!(Buffer::<f32>::mapped(&map, 4098, 8).is_none());
        assert!(Buffer::<f32>::mapped(&map, 4096, 6).is_none());
    }
}
