//! Bounded-memory decimation of a stream for plotting: min and max per bucket.
//!
//! A series of unknown length is cut into buckets of `width` consecutive samples; each
//! bucket keeps its smallest and largest value with their times. When the buckets would
//! exceed the capacity, neighbours are merged in pairs and `width` doubles. So memory is at
//! most `capacity` buckets whatever the length, the last bucket may be partial, and every
//! sample's value lies inside the plotted envelope (peaks are never lost, which plain
//! sub-sampling would do). Drawing the min and max of each bucket, in time order, as one
//! line gives the same picture as the full series when a bucket is about a pixel wide.

/// One bucket: smallest and largest value, each with its time.
#[derive(Debug, Clone, Copy)]
struct Bucket {
    lo: (f64, f64),
    hi: (f64, f64),
}

impl Bucket {
    fn merge(a: Self, b: Self) -> Self {
        Self {
            lo: if b.lo.1 < a.lo.1 { b.lo } else { a.lo },
            hi: if b.hi.1 > a.hi.1 { b.hi } else { a.hi },
        }
    }
}

/// Min/max decimator (see the module docs).
#[derive(Debug, Clone)]
pub struct MinMax {
    capacity: usize,
    width: u64,
    n: u64,
    buckets: Vec<Bucket>,
}

/// Default number of buckets: about two per horizontal pixel of a 900-pixel plot.
pub const DEFAULT_BUCKETS: usize = 2048;

impl Default for MinMax {
    fn default() -> Self {
        Self::new(DEFAULT_BUCKETS)
    }
}

impl MinMax {
    /// A decimator keeping at most `capacity` buckets (rounded up to an even number >= 2).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(2).next_multiple_of(2);
        Self {
            capacity,
            width: 1,
            n: 0,
            buckets: Vec::new(),
        }
    }

    /// Adds one sample at time `t_s`; non-finite values are ignored (they take no bucket).
    pub fn push(&mut self, t_s: f64, v: f64) {
        if !(v.is_finite() && t_s.is_finite()) {
            return;
        }
        let id = self.n / self.width;
        self.n += 1;
        if let Some(b) = usize::try_from(id)
            .ok()
            .and_then(|i| self.buckets.get_mut(i))
        {
            *b = Bucket::merge(
                *b,
                Bucket {
                    lo: (t_s, v),
                    hi: (t_s, v),
                },
            );
            return;
        }
        if self.buckets.len() == self.capacity {
            // Every bucket is full here (n was capacity * width): halve them.
            let merged: Vec<Bucket> = self
                .buckets
                .chunks(2)
                .filter_map(|c| c.iter().copied().reduce(Bucket::merge))
                .collect();
            self.buckets = merged;
            self.width *= 2;
        }
        self.buckets.push(Bucket {
            lo: (t_s, v),
            hi: (t_s, v),
        });
    }

    /// Samples pushed (finite ones).
    pub fn len(&self) -> u64 {
        self.n
    }

    /// Whether nothing was pushed.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Samples per bucket now.
    pub fn width(&self) -> u64 {
        self.width
    }

    /// The points to draw: each bucket's min and max in time order.
    pub fn points(&self) -> Vec<(f64, f64)> {
        let mut out = Vec::with_capacity(2 * self.buckets.len());
        for b in &self.buckets {
            let (first, second) = if b.lo.0 <= b.hi.0 {
                (b.lo, b.hi)
            } else {
                (b.hi, b.lo)
            };
            out.push(first);
            if second != first {
                out.push(second);
            }
        }
        out
    }

    /// Smallest and largest value seen, if any.
    pub fn range(&self) -> Option<(f64, f64)> {
        let lo = self.buckets.iter().map(|b| b.lo.1).reduce(f64::min)?;
        let hi = self.buckets.iter().map(|b| b.hi.1).reduce(f64::max)?;
        Some((lo, hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounded_and_keeps_the_extremes() {
        let mut d = MinMax::new(16);
        let n = 10_000u32;
        for i in 0..n {
            let v = if i == 7777 {
                100.0
            } else if i == 1234 {
                -50.0
            } else {
                f64::from(i % 10)
            };
            d.push(f64::from(i), v);
        }
        assert_eq!(d.len(), u64::from(n));
        assert!(d.points().len() <= 32);
        assert_eq!(d.range(), Some((-50.0, 100.0)));
        let p = d.points();
        assert!(p.windows(2).all(|w| w[0].0 <= w[1].0), "time order");
        assert!(p.contains(&(7777.0, 100.0)) && p.contains(&(1234.0, -50.0)));
    }

    #[test]
    fn short_series_is_kept_whole() {
        let mut d = MinMax::new(8);
        for i in 0..5 {
            d.push(f64::from(i), f64::from(i));
        }
        assert_eq!(d.points().len(), 5);
        assert_eq!(d.width(), 1);
    }
}
