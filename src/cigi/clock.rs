//! The IG's estimate of the host's clock: which host time a local instant is.
//!
//! Each accepted datagram gives one measurement `arrival − host time` (the host time from IG
//! Control's timestamp, or the arrival itself when the timestamp is not valid). An arrival is
//! taken when the IG reads the datagram, which is at some frame start after it came in, so a
//! measurement is the true clock offset plus a transport latency plus a reading delay of up to
//! a frame. The estimate is the **lowest** measurement of the last [`WINDOW`] seconds (the
//! datagram read soonest after it was sent), and the offset in use moves towards it by at most
//! [`SLEW`] seconds per second of local time, so the host time of successive IG frames never
//! steps; a difference beyond [`RESET`] (a clock jump) is taken at once. For the first
//! [`ACQUIRE`] seconds after the first datagram (or a [`HostClock::restart`]) the estimate is
//! taken without slewing: the first datagrams are often read late (the IG still starting), and
//! a host time that lags by more than a sample interval would show held samples.

use std::collections::VecDeque;

/// Seconds of measurements the lowest is taken from.
pub const WINDOW: f64 = 2.0;
/// Largest change of the offset in use per second of local time (5 %).
pub const SLEW: f64 = 0.05;
/// A difference from the offset in use larger than this (s) replaces it at once.
pub const RESET: f64 = 0.5;
/// Seconds after the first datagram during which the lowest measurement is taken at once.
pub const ACQUIRE: f64 = 1.0;
/// Most measurements held (a flood of valid datagrams cannot grow the window).
pub const MAX_HELD: usize = 4096;

/// Local − host clock offset estimate.
#[derive(Clone, Debug, Default)]
pub struct HostClock {
    /// The offset in use at local time `updated`, and the estimate it moves towards.
    offset: Option<f64>,
    target: f64,
    /// Local time of the first measurement.
    first: f64,
    updated: f64,
    /// `(local time, measurement)`, measurements increasing front to back (a monotonic queue:
    /// the front is the window's lowest).
    window: VecDeque<(f64, f64)>,
}

impl HostClock {
    /// A datagram that arrived at local time `now` for host time `host`.
    pub fn observe(&mut self, now: f64, host: f64) {
        let m = now - host;
        if !m.is_finite() {
            return;
        }
        while self
            .window
            .front()
            .is_some_and(|&(t, _)| t < now - WINDOW || t > now)
            || self.window.len() >= MAX_HELD
        {
            self.window.pop_front();
        }
        while self.window.back().is_some_and(|&(_, b)| b >= m) {
            self.window.pop_back();
        }
        self.window.push_back((now, m));
        let target = self.window.front().map_or(m, |&(_, b)| b);
        let current = self.offset_at(now);
        if current.is_none() {
            self.first = now;
        }
        self.offset = Some(match current {
            Some(o) if (target - o).abs() <= RESET && now - self.first > ACQUIRE => o,
            _ => target,
        });
        self.target = target;
        self.updated = now;
    }

    /// Forgets every measurement (the host's timestamps went back: a host restarted).
    pub fn restart(&mut self) {
        *self = HostClock::default();
    }

    /// The offset in use (local − host, s) at local time `now`, once a datagram was seen: it
    /// moves from its value at the last datagram towards the estimate at [`SLEW`] s/s, so the
    /// host time it gives advances at 0.95..1.05 times the local clock's rate.
    pub fn offset_at(&self, now: f64) -> Option<f64> {
        let o = self.offset?;
        let step = SLEW * (now - self.updated).max(0.0);
        Some(o + (self.target - o).clamp(-step, step))
    }

    /// The host time at local time `now`, once a datagram was seen.
    pub fn host_time_at(&self, now: f64) -> Option<f64> {
        self.offset_at(now).map(|o| now - o)
    }
}
