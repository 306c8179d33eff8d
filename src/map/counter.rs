//! A visibility counter that tracking bumps under the map's read lock.

use std::sync::atomic::{AtomicU32, Ordering};

/// A `u32` counter shared between threads without a write lock
/// (ORB-SLAM3's `mnVisible` / `mnFound`, which it guards with a mutex per
/// point). Relaxed ordering: the counts are statistics read by culling, and
/// no other memory is published through them.
#[derive(Debug, Default)]
pub struct Counter(AtomicU32);

impl Counter {
    /// A counter starting at `value`.
    pub fn new(value: u32) -> Self {
        Self(AtomicU32::new(value))
    }

    /// The current count.
    pub fn get(&self) -> u32 {
        self.0.load(Ordering::Relaxed)
    }

    /// Adds `n` (saturating at `u32::MAX`) through a shared reference.
    pub fn add(&self, n: u32) {
        // fetch_update never fails with a closure that always returns Some.
        let _ = self
            .0
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |v| {
                Some(v.saturating_add(n))
            });
    }

    /// Adds one.
    pub fn increment(&self) {
        self.add(1);
    }

    /// Overwrites the count (tests, map loading).
    pub fn set(&mut self, value: u32) {
        *self.0.get_mut() = value;
    }
}

impl Clone for Counter {
    fn clone(&self) -> Self {
        Self::new(self.get())
    }
}

impl PartialEq for Counter {
    fn eq(&self, other: &Self) -> bool {
        self.get() == other.get()
    }
}

impl PartialEq<u32> for Counter {
    fn eq(&self, other: &u32) -> bool {
        self.get() == *other
    }
}

#[cfg(test)]
mod tests {
    use super::Counter;

    #[test]
    fn concurrent_increments_are_all_counted() {
        let counter = Counter::new(1);
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| {
                    for _ in 0..10_000 {
                        counter.increment();
                    }
                });
            }
        });
        assert_eq!(counter.get(), 40_001);
    }

    #[test]
    fn add_saturates() {
        let counter = Counter::new(u32::MAX - 1);
        counter.add(5);
        assert_eq!(counter.get(), u32::MAX);
    }
}
