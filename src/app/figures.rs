//! Statistics shared by the benchmarks, the soak run and the window's frame loop: median,
//! percentile, least-squares slope (also fed one value at a time, in bounded memory, for runs
//! of any length: [`Percentiles`], [`SlopeFit`]), the window a memory slope is fitted over, and
//! the process's resident set size.

/// Median of a non-empty sample (mean of the middle two for an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Percentile (nearest rank) of unsorted values; NaNs are ignored. `None` when empty.
pub fn percentile(values: &[f64], p: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * v.len() as f64).ceil().max(1.0) as usize;
    Some(v[rank.min(v.len()) - 1])
}

/// Least-squares slope of `y` over `x = 0, 1, 2, ...` (0 for fewer than two points).
pub fn slope(y: &[f64]) -> f64 {
    let n = y.len() as f64;
    if y.len() < 2 {
        return 0.0;
    }
    let mx = (n - 1.0) / 2.0;
    let my = y.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in y.iter().enumerate() {
        let dx = i as f64 - mx;
        sxy += dx * (v - my);
        sxx += dx * dx;
    }
    sxy / sxx
}

/// The frame window a memory slope is fitted over: 100..500 (the first frames warm caches and
/// compile pipelines), shrunk for shorter runs.
pub fn window(frames: u32) -> [u32; 2] {
    if frames >= 500 {
        [100, 500]
    } else {
        [frames / 5, frames]
    }
}

/// The process's resident set size in KiB (Linux: `VmRSS` of `/proc/self/status`).
pub fn resident_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Nearest-rank percentiles of a stream of values in bounded memory, for runs of any length (a
/// window left open for hours): a logarithmic histogram of 0.1%-wide buckets, each keeping its
/// count and the smallest value it saw. The answer is that smallest value of the bucket the
/// rank falls in: at most 0.1% below [`percentile`]'s over the same values, and equal to it
/// where the bucket saw one distinct value. Values at or below zero share one bucket; NaNs
/// are ignored. At most one bucket per 0.1% of the values' range (about 16,000 from 1 µs to
/// 10 s), usually a few hundred.
#[derive(Clone, Debug, Default)]
pub struct Percentiles {
    buckets: std::collections::BTreeMap<i32, (u64, f64)>,
    count: u64,
}

impl Percentiles {
    /// Adds one value.
    pub fn add(&mut self, v: f64) {
        if v.is_nan() {
            return;
        }
        let key = if v <= 0.0 {
            i32::MIN
        } else {
            // Saturating: +inf lands in the last bucket.
            (v.ln() / 1.001f64.ln()).floor() as i32
        };
        let b = self.buckets.entry(key).or_insert((0, v));
        b.0 += 1;
        b.1 = b.1.min(v);
        self.count += 1;
    }

    /// Percentile `p` (nearest rank, as [`percentile`]); `None` when no value was added.
    pub fn get(&self, p: f64) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let rank = (((p / 100.0) * self.count as f64).ceil().max(1.0) as u64).min(self.count);
        let mut seen = 0;
        for (n, smallest) in self.buckets.values() {
            seen += n;
            if seen >= rank {
                return Some(*smallest);
            }
        }
        None
    }
}

/// Least-squares slope of y over x, fed one point at a time in constant memory (Welford's
/// updates of the means and co-moments: no cancellation over millions of points).
#[derive(Clone, Copy, Debug, Default)]
pub struct SlopeFit {
    n: f64,
    mx: f64,
    my: f64,
    sxx: f64,
    sxy: f64,
}

impl SlopeFit {
    /// Adds the point (x, y).
    pub fn add(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        let dx = x - self.mx;
        self.mx += dx / self.n;
        self.my += (y - self.my) / self.n;
        self.sxx += dx * (x - self.mx);
        self.sxy += dx * (y - self.my);
    }

    /// The points added.
    pub fn points(&self) -> u64 {
        self.n as u64
    }

    /// The slope (0 for fewer than two distinct x).
    pub fn slope(&self) -> f64 {
        if self.sxx > 0.0 {
            self.sxy / self.sxx
        } else {
            0.0
        }
    }
}
