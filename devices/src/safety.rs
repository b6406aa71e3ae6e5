//! The safety filter: the only path by which force reaches a device.
//!
//! Guarantee: every force passed to [`SafetyFilter::write_force`] reaches the wrapped device
//! finite, no larger than the device's (and the configuration's) maximum, changing no faster
//! than the slew-rate limit, scaled by a soft-start ramp after forces are enabled, and as exact
//! zero while a device fault is latched. The filter allocates nothing and takes no lock after
//! construction; each call does constant work plus one call into the device.
//!
//! Time comes from the device's own sample timestamps (the last successful `read`), not a wall
//! clock, so a replayed session filters bit for bit as it did live. A repeated (stale) sample
//! carries no new time, so the slew limit grants no change for that write and the output holds.

use glam::Vec3;

use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};

/// Settings of a [`SafetyFilter`]; `Default` gives the recommended values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SafetyConfig {
    /// Upper bound on the force magnitude, newtons. The effective bound is the smaller of this
    /// and the device's [`DeviceInfo::max_force_n`]; `f32::INFINITY` defers to the device.
    pub max_force_n: f32,
    /// Largest change of the output force per second, newtons per second (per vector, by
    /// magnitude of the change).
    pub slew_rate_n_per_s: f32,
    /// Duration of the soft-start ramp after forces are enabled or a fault clears, seconds
    /// (CHAI3D's tools ramp over 2 s). Zero disables the ramp.
    pub soft_start_s: f32,
    /// Longest time step the slew limit will credit between two writes, seconds, so a pause
    /// (a stalled loop, a gap in the samples) does not permit a sudden jump.
    pub max_step_s: f32,
    /// Whether forces are enabled as soon as the device opens (with a soft start). When
    /// `false`, nothing but zero is sent until [`SafetyFilter::set_forces_enabled`].
    pub enable_on_open: bool,
}

impl SafetyConfig {
    /// Default slew-rate limit: 1 N per millisecond.
    pub const DEFAULT_SLEW_RATE_N_PER_S: f32 = 1000.0;
    /// Default soft-start duration, seconds.
    pub const DEFAULT_SOFT_START_S: f32 = 2.0;
    /// Default longest credited step, seconds.
    pub const DEFAULT_MAX_STEP_S: f32 = 0.01;
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            max_force_n: f32::INFINITY,
            slew_rate_n_per_s: Self::DEFAULT_SLEW_RATE_N_PER_S,
            soft_start_s: Self::DEFAULT_SOFT_START_S,
            max_step_s: Self::DEFAULT_MAX_STEP_S,
            enable_on_open: true,
        }
    }
}

/// What the filter has done since the device was opened (reset by `open`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SafetyCounters {
    /// Forces passed to `write_force`.
    pub writes: u64,
    /// Forces with a NaN or infinite component, replaced by zero.
    pub nonfinite: u64,
    /// Forces whose magnitude was clamped to the maximum.
    pub clamped: u64,
    /// Writes whose change was cut by the slew-rate limit.
    pub slew_limited: u64,
    /// Device errors from `read`.
    pub read_faults: u64,
    /// Device errors from `write_force`.
    pub write_faults: u64,
    /// Soft starts begun (forces enabled, or a fault cleared).
    pub soft_starts: u64,
}

/// Smooth soft-start gain for progress `t` in `[0, 1]`: the smoothstep `3t² − 2t³`, which
/// starts and ends with zero slope so the ramp itself adds no jolt.
#[must_use]
pub fn soft_start_gain(t: f32) -> f32 {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    t * t * (3.0 - 2.0 * t)
}

/// Wraps a device so that force reaches it only through the checks listed in the module docs.
///
/// The filter is itself a [`HapticDevice`]: `read` passes samples through (recording faults and
/// the time base), `write_force` filters. On any device error it immediately sends zero, and
/// keeps sending zero until a `read` succeeds again; then force comes back through a fresh soft
/// start.
///
/// # Examples
///
/// A haptic loop over the simulated arm, recording the session; the force the engine asks
/// for is clamped, slewed and ramped before it reaches the arm.
///
/// ```
/// use dynaclay_devices::{HapticDevice, RecordingDevice, SafetyFilter, SimulatedArm, Trajectory};
/// use glam::Vec3;
///
/// let dir = tempfile::tempdir()?;
/// let arm = SimulatedArm::with_trajectory(Trajectory::hold(Vec3::ZERO));
/// let recorder = RecordingDevice::create(arm, dir.path().join("session.dcrec"))?;
/// let mut device = SafetyFilter::new(recorder);
/// device.open()?;
/// for _ in 0..1000 {
///     match device.read() {
///         Ok(state) => device.write_force(-state.position_m * 500.0)?,
///         // The filter already sent zero; keep ticking.
///         Err(_) => continue,
///     }
/// }
/// assert!(device.output_force_n().length() <= device.max_force_n());
/// let (_arm, summary) = device.into_inner().finish()?;
/// assert_eq!(summary.records, 2000);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct SafetyFilter<D: HapticDevice = Box<dyn HapticDevice>> {
    /// Always `Some` while the filter lives: only [`SafetyFilter::into_inner`], which consumes
    /// the filter, takes it out (a filter that implements `Drop` cannot move a field out).
    device: Option<D>,
    config: SafetyConfig,
    /// Effective magnitude bound, newtons (min of config and device info), refreshed on open.
    limit_n: f32,
    /// The device's own bound from its info, newtons, cached so a new configured bound is
    /// applied without asking the device (whose info may allocate).
    device_limit_n: f32,
    /// Whether the device outputs force ([`DeviceInfo::has_force`]), cached with the bound.
    has_force: bool,
    enabled: bool,
    /// A device error was seen and no successful read has followed yet.
    fault_latched: bool,
    /// Device time at which the current soft start began, if one is running or done.
    ramp_start_us: Option<u64>,
    /// Timestamp of the last successful read, microseconds of device time.
    now_us: u64,
    /// Device time of the previous write (`None` before the first).
    last_write_us: Option<u64>,
    /// The force most recently sent to the device, newtons.
    output_n: Vec3,
    counters: SafetyCounters,
}

impl<D: HapticDevice> SafetyFilter<D> {
    /// Wraps `device` with the default settings.
    #[must_use]
    pub fn new(device: D) -> Self {
        Self::with_config(device, SafetyConfig::default())
    }

    /// Wraps `device` with `config`.
    #[must_use]
    pub fn with_config(device: D, config: SafetyConfig) -> Self {
        let info = device.info();
        let device_limit_n = device_limit(&info);
        Self {
            device: Some(device),
            config,
            limit_n: effective_limit(&config, device_limit_n),
            device_limit_n,
            has_force: info.has_force,
            enabled: false,
            fault_latched: false,
            ramp_start_us: None,
            now_us: 0,
            last_write_us: None,
            output_n: Vec3::ZERO,
            counters: SafetyCounters::default(),
        }
    }

    /// The settings in use.
    #[must_use]
    pub fn config(&self) -> &SafetyConfig {
        &self.config
    }

    /// The wrapped device.
    #[must_use]
    pub fn device(&self) -> &D {
        self.dev()
    }

    /// The wrapped device, mutably. Forces written through this reference bypass the filter;
    /// use it for driver-specific settings only.
    pub fn device_mut(&mut self) -> &mut D {
        self.dev_mut()
    }

    /// Unwraps the device (without closing it).
    #[must_use]
    pub fn into_inner(mut self) -> D {
        self.device
            .take()
            .unwrap_or_else(|| unreachable!("the device leaves the filter only here"))
    }

    fn dev(&self) -> &D {
        self.device
            .as_ref()
            .unwrap_or_else(|| unreachable!("the device leaves the filter only with it"))
    }

    fn dev_mut(&mut self) -> &mut D {
        self.device
            .as_mut()
            .unwrap_or_else(|| unreachable!("the device leaves the filter only with it"))
    }

    /// The effective force bound, newtons.
    #[must_use]
    pub fn max_force_n(&self) -> f32 {
        self.limit_n
    }

    /// Whether the device outputs force (from its info at construction or the last open,
    /// so asking allocates nothing).
    #[must_use]
    pub fn has_force(&self) -> bool {
        self.has_force
    }

    /// The force most recently sent to the device, newtons.
    #[must_use]
    pub fn output_force_n(&self) -> Vec3 {
        self.output_n
    }

    /// Sets the configured force bound to `max_force_n` newtons from the next write on; the
    /// effective bound ([`SafetyFilter::max_force_n`]) stays at most the device's own maximum
    /// (as of the last `open`). NaN and negative values mean zero, `f32::INFINITY` defers to
    /// the device. A lower bound holds from the next write on, even if that drops the output
    /// faster than the slew limit; a higher one is reached through the slew limit.
    ///
    /// Constant work, no allocation, no device call: safe on the haptic path.
    pub fn set_max_force_n(&mut self, max_force_n: f32) {
        self.config.max_force_n = max_force_n;
        self.limit_n = effective_limit(&self.config, self.device_limit_n);
    }

    /// Counters since the last `open`.
    #[must_use]
    pub fn counters(&self) -> SafetyCounters {
        self.counters
    }

    /// Whether a device fault is latched (only zero is sent until a read succeeds).
    #[must_use]
    pub fn fault_latched(&self) -> bool {
        self.fault_latched
    }

    /// Whether forces are enabled.
    #[must_use]
    pub fn forces_enabled(&self) -> bool {
        self.enabled
    }

    /// Current soft-start gain in `[0, 1]` (0 while disabled or faulted).
    #[must_use]
    pub fn soft_start_gain(&self) -> f32 {
        if !self.enabled || self.fault_latched {
            return 0.0;
        }
        match self.ramp_start_us {
            None => 0.0,
            Some(_) if self.config.soft_start_s <= 0.0 => 1.0,
            Some(start) => {
                let elapsed_s = self.now_us.saturating_sub(start) as f32 * 1e-6;
                soft_start_gain(elapsed_s / self.config.soft_start_s)
            }
        }
    }

    /// Enables or disables force output. Enabling starts a soft start from the current device
    /// time; disabling sends zero at the next write (immediately, not slew-limited).
    pub fn set_forces_enabled(&mut self, enabled: bool) {
        if enabled && !self.enabled {
            self.begin_soft_start();
        }
        if !enabled {
            self.ramp_start_us = None;
        }
        self.enabled = enabled;
    }

    fn begin_soft_start(&mut self) {
        self.ramp_start_us = Some(self.now_us);
        self.counters.soft_starts += 1;
    }

    /// Latches a fault: best-effort zero to the device, output forgotten.
    fn latch_fault(&mut self) {
        self.fault_latched = true;
        self.ramp_start_us = None;
        self.output_n = Vec3::ZERO;
        // NOTE: the result is ignored on purpose: the device already failed once, and the
        // caller gets that first error.
        let _ = self.dev_mut().write_force(Vec3::ZERO);
    }

    /// Runs the checks on `requested_n` and returns what should be sent, updating counters
    /// and the time base. Pure arithmetic: no device call.
    fn filter(&mut self, requested_n: Vec3) -> Vec3 {
        self.counters.writes += 1;
        let dt_s = match self.last_write_us {
            Some(prev) if self.now_us >= prev => {
                ((self.now_us - prev) as f32 * 1e-6).min(self.config.max_step_s)
            }
            _ => 0.0,
        };
        self.last_write_us = Some(self.now_us);

        let mut force = requested_n;
        if !force.is_finite() {
            self.counters.nonfinite += 1;
            force = Vec3::ZERO;
        }
        if self.fault_latched || !self.enabled {
            return Vec3::ZERO;
        }
        let magnitude = force.length();
        if magnitude > self.limit_n {
            self.counters.clamped += 1;
            force *= self.limit_n / magnitude;
        }
        force *= self.soft_start_gain();

        let max_step_n = self.config.slew_rate_n_per_s * dt_s;
        let change = force - self.output_n;
        let change_n = change.length();
        if change_n > max_step_n {
            self.counters.slew_limited += 1;
            force = if change_n > 0.0 && max_step_n > 0.0 {
                self.output_n + change * (max_step_n / change_n)
            } else {
                self.output_n
            };
            // A bound lowered while running holds at once: slewing down from the old output
            // must not leave the force above the new bound.
            let slewed_n = force.length();
            if slewed_n > self.limit_n {
                force *= self.limit_n / slewed_n;
            }
        }
        force
    }
}

fn device_limit(info: &DeviceInfo) -> f32 {
    if info.max_force_n.is_finite() && info.max_force_n >= 0.0 {
        info.max_force_n
    } else {
        0.0
    }
}

fn effective_limit(config: &SafetyConfig, device: f32) -> f32 {
    let configured = if config.max_force_n.is_nan() {
        0.0
    } else {
        config.max_force_n.max(0.0)
    };
    device.min(configured)
}

/// A filter dropped with its device still open closes it, commanding zero force first (every
/// driver's `close` does), so no path that loses the filter (a loop handle or an engine
/// dropped without being stopped, a thread unwinding) leaves the arm pushing with its last
/// force. A close that fails here has nowhere to go; the device was told zero as far as it
/// could be.
impl<D: HapticDevice> Drop for SafetyFilter<D> {
    fn drop(&mut self) {
        if let Some(device) = self.device.as_mut()
            && device.is_open()
        {
            self.output_n = Vec3::ZERO;
            self.enabled = false;
            let _ = device.close();
        }
    }
}

impl<D: HapticDevice> HapticDevice for SafetyFilter<D> {
    fn info(&self) -> DeviceInfo {
        let mut info = self.dev().info();
        info.max_force_n = info.max_force_n.min(self.limit_n);
        info
    }

    /// Opens the device, resets counters and the time base, and (with `enable_on_open`)
    /// enables forces with a soft start.
    fn open(&mut self) -> Result<(), DeviceError> {
        self.dev_mut().open()?;
        let info = self.dev().info();
        self.device_limit_n = device_limit(&info);
        self.has_force = info.has_force;
        self.limit_n = effective_limit(&self.config, self.device_limit_n);
        self.counters = SafetyCounters::default();
        self.fault_latched = false;
        self.now_us = 0;
        self.last_write_us = None;
        self.output_n = Vec3::ZERO;
        self.enabled = false;
        self.ramp_start_us = None;
        if self.config.enable_on_open {
            // The time base is set by the first read; the ramp restarts there.
            self.enabled = true;
        }
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        self.output_n = Vec3::ZERO;
        self.enabled = false;
        self.ramp_start_us = None;
        self.dev_mut().close()
    }

    fn is_open(&self) -> bool {
        self.dev().is_open()
    }

    /// Reads the device. An error latches the fault and sends zero at once; the first success
    /// after a fault clears it and begins a fresh soft start.
    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        match self.dev_mut().read() {
            Ok(state) => {
                if state.timestamp_us < self.now_us {
                    // The device clock restarted (reopened underneath us): restart the slew
                    // time base rather than crediting a negative or huge step.
                    self.last_write_us = None;
                    if self.ramp_start_us.is_some() {
                        self.ramp_start_us = Some(state.timestamp_us);
                    }
                }
                self.now_us = state.timestamp_us;
                if self.fault_latched {
                    self.fault_latched = false;
                    if self.enabled {
                        self.begin_soft_start();
                    }
                } else if self.enabled && self.ramp_start_us.is_none() {
                    // First sample after open: the soft start begins at device time zero-point.
                    self.begin_soft_start();
                }
                Ok(state)
            }
            Err(err) => {
                self.counters.read_faults += 1;
                self.latch_fault();
                Err(err)
            }
        }
    }

    /// Filters `force_n` and sends it. On a device error the fault latches (zero is sent at
    /// once and until a read succeeds) and the error is returned.
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        let out = self.filter(force_n);
        match self.dev_mut().write_force(out) {
            Ok(()) => {
                self.output_n = out;
                Ok(())
            }
            Err(err) => {
                self.counters.write_faults += 1;
                self.latch_fault();
                Err(err)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scripted device: time advances 1 ms per read; errors can be queued.
    struct Probe {
        open: bool,
        t_us: u64,
        fail_reads: u32,
        fail_writes: u32,
        written: Vec<Vec3>,
    }

    impl Probe {
        fn new() -> Self {
            Self {
                open: false,
                t_us: 0,
                fail_reads: 0,
                fail_writes: 0,
                written: Vec::new(),
            }
        }
    }

    impl HapticDevice for Probe {
        fn info(&self) -> DeviceInfo {
            DeviceInfo {
                name: "probe".into(),
                dof: 3,
                max_force_n: 5.0,
                max_stiffness_n_per_m: 2000.0,
                max_damping_n_s_per_m: 10.0,
                workspace_min_m: Vec3::splat(-0.1),
                workspace_max_m: Vec3::splat(0.1),
                has_orientation: false,
                has_force: true,
                button_count: 1,
                sample_rate_hz: 1000.0,
            }
        }
        fn open(&mut self) -> Result<(), DeviceError> {
            self.open = true;
            self.t_us = 0;
            Ok(())
        }
        fn close(&mut self) -> Result<(), DeviceError> {
            self.open = false;
            Ok(())
        }
        fn is_open(&self) -> bool {
            self.open
        }
        fn read(&mut self) -> Result<DeviceState, DeviceError> {
            if self.fail_reads > 0 {
                self.fail_reads -= 1;
                return Err(DeviceError::Disconnected);
            }
            let s = DeviceState {
                timestamp_us: self.t_us,
                sequence: self.t_us / 1000,
                ..DeviceState::ZERO
            };
            self.t_us += 1000;
            Ok(s)
        }
        fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
            self.written.push(force_n);
            if self.fail_writes > 0 {
                self.fail_writes -= 1;
                return Err(DeviceError::Timeout { waited_us: 1000 });
            }
            Ok(())
        }
    }

    fn no_ramp() -> SafetyConfig {
        SafetyConfig {
            soft_start_s: 0.0,
            slew_rate_n_per_s: 1e9,
            ..SafetyConfig::default()
        }
    }

    fn tick(f: &mut SafetyFilter<Probe>, force: Vec3) -> Vec3 {
        f.read().unwrap();
        f.write_force(force).unwrap();
        f.output_force_n()
    }

    /// A device that notes, where its owner can see after the filter is gone, whether it is
    /// still open and the last force it was sent.
    struct Noted {
        probe: Probe,
        note: std::sync::Arc<std::sync::Mutex<(bool, Vec3)>>,
    }

    impl HapticDevice for Noted {
        fn info(&self) -> DeviceInfo {
            self.probe.info()
        }
        fn open(&mut self) -> Result<(), DeviceError> {
            self.note.lock().unwrap().0 = true;
            self.probe.open()
        }
        fn close(&mut self) -> Result<(), DeviceError> {
            // As every driver's close: zero force first.
            self.write_force(Vec3::ZERO)?;
            self.note.lock().unwrap().0 = false;
            self.probe.close()
        }
        fn is_open(&self) -> bool {
            self.probe.is_open()
        }
        fn read(&mut self) -> Result<DeviceState, DeviceError> {
            self.probe.read()
        }
        fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
            self.note.lock().unwrap().1 = force_n;
            self.probe.write_force(force_n)
        }
    }

    /// Dropped while its device is open and pushing, the filter closes the device, which
    /// leaves it at zero force; unwrapped with `into_inner`, the device stays open for its
    /// new owner.
    #[test]
    fn a_dropped_filter_closes_its_open_device_and_into_inner_does_not() {
        let note = std::sync::Arc::new(std::sync::Mutex::new((false, Vec3::ZERO)));
        let device = || Noted {
            probe: Probe::new(),
            note: note.clone(),
        };
        let mut f = SafetyFilter::with_config(device(), no_ramp());
        f.open().unwrap();
        f.read().unwrap();
        f.write_force(Vec3::X * 2.0).unwrap();
        f.read().unwrap();
        f.write_force(Vec3::X * 2.0).unwrap();
        assert_eq!(*note.lock().unwrap(), (true, Vec3::X * 2.0));
        drop(f);
        assert_eq!(*note.lock().unwrap(), (false, Vec3::ZERO));

        let mut f = SafetyFilter::with_config(device(), no_ramp());
        f.open().unwrap();
        let inner = f.into_inner();
        assert!(inner.is_open());
        assert!(note.lock().unwrap().0);
    }

    #[test]
    fn nan_and_infinity_become_zero() {
        let mut f = SafetyFilter::with_config(Probe::new(), no_ramp());
        f.open().unwrap();
        tick(&mut f, Vec3::ZERO);
        assert_eq!(tick(&mut f, Vec3::new(f32::NAN, 1.0, 0.0)), Vec3::ZERO);
        assert_eq!(tick(&mut f, Vec3::new(0.0, f32::INFINITY, 0.0)), Vec3::ZERO);
        assert_eq!(tick(&mut f, Vec3::splat(f32::NEG_INFINITY)), Vec3::ZERO);
        assert_eq!(f.counters().nonfinite, 3);
        assert!(f.device().written.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn magnitude_clamped_to_device_and_config_max() {
        let mut f = SafetyFilter::with_config(Probe::new(), no_ramp());
        f.open().unwrap();
        tick(&mut f, Vec3::ZERO);
        let out = tick(&mut f, Vec3::new(30.0, 40.0, 0.0));
        assert!((out.length() - 5.0).abs() < 1e-5, "{out}");
        // Direction kept.
        assert!((out.normalize() - Vec3::new(0.6, 0.8, 0.0)).length() < 1e-6);
        assert_eq!(f.counters().clamped, 1);

        let mut f = SafetyFilter::with_config(
            Probe::new(),
            SafetyConfig {
                max_force_n: 2.0,
                ..no_ramp()
            },
        );
        f.open().unwrap();
        tick(&mut f, Vec3::ZERO);
        assert!((tick(&mut f, Vec3::X * 4.0).length() - 2.0).abs() < 1e-6);
        assert_eq!(f.info().max_force_n, 2.0);
    }

    #[test]
    fn max_force_changes_while_running_and_never_exceeds_the_device() {
        let mut f = SafetyFilter::with_config(Probe::new(), no_ramp());
        f.open().unwrap();
        tick(&mut f, Vec3::ZERO);
        assert!((tick(&mut f, Vec3::X * 30.0).length() - 5.0).abs() < 1e-5);
        // Lowering the bound clamps the very next write.
        f.set_max_force_n(1.5);
        assert_eq!(f.max_force_n(), 1.5);
        assert_eq!(f.config().max_force_n, 1.5);
        assert!((tick(&mut f, Vec3::X * 30.0).length() - 1.5).abs() < 1e-6);
        // Even under a slow slew limit, the lower bound is not slewed down to.
        let mut slow = SafetyFilter::with_config(
            Probe::new(),
            SafetyConfig {
                slew_rate_n_per_s: 1000.0,
                ..no_ramp()
            },
        );
        slow.open().unwrap();
        for _ in 0..10 {
            tick(&mut slow, Vec3::X * 30.0);
        }
        assert!((slow.output_force_n().length() - 5.0).abs() < 1e-5);
        slow.set_max_force_n(0.5);
        assert!((tick(&mut slow, Vec3::X * 30.0).length() - 0.5).abs() < 1e-6);
        // Above the device's own maximum (5 N) the device's bound holds.
        f.set_max_force_n(50.0);
        assert_eq!(f.max_force_n(), 5.0);
        assert_eq!(f.info().max_force_n, 5.0);
        assert!((tick(&mut f, Vec3::X * 30.0).length() - 5.0).abs() < 1e-5);
        f.set_max_force_n(f32::INFINITY);
        assert_eq!(f.max_force_n(), 5.0);
        // Nonsense means no force, never more.
        f.set_max_force_n(f32::NAN);
        assert_eq!(f.max_force_n(), 0.0);
        assert_eq!(tick(&mut f, Vec3::X * 30.0), Vec3::ZERO);
        f.set_max_force_n(-3.0);
        assert_eq!(f.max_force_n(), 0.0);
        // The bound survives a reopen.
        f.set_max_force_n(2.0);
        f.close().unwrap();
        f.open().unwrap();
        assert_eq!(f.max_force_n(), 2.0);
    }

    #[test]
    fn slew_rate_limits_change_per_tick() {
        let mut f = SafetyFilter::with_config(
            Probe::new(),
            SafetyConfig {
                slew_rate_n_per_s: 500.0,
                ..no_ramp()
            },
        );
        f.open().unwrap();
        tick(&mut f, Vec3::ZERO);
        // 1 ms per tick at 500 N/s: 0.5 N per tick, toward the 4 N target.
        let mut prev = Vec3::ZERO;
        for i in 1..=8 {
            let out = tick(&mut f, Vec3::Y * 4.0);
            assert!(
                ((out - prev).length() - 0.5).abs() < 1e-5,
                "tick {i}: {out}"
            );
            prev = out;
        }
        assert!((prev.y - 4.0).abs() < 1e-5);
        assert_eq!(tick(&mut f, Vec3::Y * 4.0), Vec3::Y * 4.0);
        assert_eq!(f.counters().slew_limited, 7);
        // Dropping to zero is also slew-limited.
        let out = tick(&mut f, Vec3::ZERO);
        assert!((out.y - 3.5).abs() < 1e-5);
    }

    #[test]
    fn slew_credit_is_capped_after_a_gap() {
        let mut f = SafetyFilter::with_config(
            Probe::new(),
            SafetyConfig {
                slew_rate_n_per_s: 100.0,
                max_step_s: 0.002,
                ..no_ramp()
            },
        );
        f.open().unwrap();
        tick(&mut f, Vec3::ZERO);
        f.device_mut().t_us += 1_000_000; // one second without writes
        let out = tick(&mut f, Vec3::X * 5.0);
        assert!((out.x - 0.2).abs() < 1e-6, "{out}");
    }

    #[test]
    fn soft_start_ramp_shape() {
        let mut f = SafetyFilter::with_config(
            Probe::new(),
            SafetyConfig {
                slew_rate_n_per_s: 1e9,
                ..SafetyConfig::default()
            },
        );
        f.open().unwrap();
        let target = Vec3::Z * 4.0;
        let mut outs = Vec::new();
        for _ in 0..=2500 {
            outs.push(tick(&mut f, target).z);
        }
        // The ramp starts at the first read (t = 0) and lasts 2 s: tick i is at t = i ms.
        assert_eq!(outs[0], 0.0);
        assert!((outs[1000] - 2.0).abs() < 1e-4, "midpoint {}", outs[1000]);
        assert!((outs[500] - 4.0 * soft_start_gain(0.25)).abs() < 1e-4);
        assert!(
            outs[500] < 1.0,
            "smoothstep is slow at first: {}",
            outs[500]
        );
        assert!((outs[2000] - 4.0).abs() < 1e-6);
        assert!(outs.windows(2).all(|w| w[1] >= w[0]), "monotone");
        assert!(outs[2000..].iter().all(|&z| z == 4.0));
        assert_eq!(f.counters().soft_starts, 1);
    }

    #[test]
    fn gain_curve_endpoints() {
        assert_eq!(soft_start_gain(0.0), 0.0);
        assert_eq!(soft_start_gain(1.0), 1.0);
        assert_eq!(soft_start_gain(0.5), 0.5);
        assert_eq!(soft_start_gain(-3.0), 0.0);
        assert_eq!(soft_start_gain(7.0), 1.0);
        assert_eq!(soft_start_gain(f32::NAN), 0.0);
    }

    #[test]
    fn disabled_sends_zero_and_enabling_ramps() {
        let mut f = SafetyFilter::with_config(
            Probe::new(),
            SafetyConfig {
                enable_on_open: false,
                soft_start_s: 0.01,
                slew_rate_n_per_s: 1e9,
                ..SafetyConfig::default()
            },
        );
        f.open().unwrap();
        for _ in 0..5 {
            assert_eq!(tick(&mut f, Vec3::X), Vec3::ZERO);
        }
        f.set_forces_enabled(true);
        let first = tick(&mut f, Vec3::X).x;
        assert!(first > 0.0 && first < 0.1, "{first}");
        for _ in 0..20 {
            tick(&mut f, Vec3::X);
        }
        assert_eq!(f.output_force_n(), Vec3::X);
        f.set_forces_enabled(false);
        assert_eq!(tick(&mut f, Vec3::X), Vec3::ZERO, "disable is immediate");
    }

    #[test]
    fn zero_after_read_error_then_fresh_soft_start() {
        let mut f = SafetyFilter::with_config(
            Probe::new(),
            SafetyConfig {
                soft_start_s: 0.1,
                slew_rate_n_per_s: 1e9,
                ..SafetyConfig::default()
            },
        );
        f.open().unwrap();
        for _ in 0..200 {
            tick(&mut f, Vec3::X * 3.0);
        }
        assert_eq!(f.output_force_n(), Vec3::X * 3.0);

        f.device_mut().fail_reads = 3;
        let before = f.device().written.len();
        for _ in 0..3 {
            assert_eq!(f.read(), Err(DeviceError::Disconnected));
            assert!(f.fault_latched());
            // The engine keeps asking for force; only zero goes out.
            f.write_force(Vec3::X * 3.0).unwrap();
        }
        let during = &f.device().written[before..];
        assert!(during.iter().all(|&v| v == Vec3::ZERO), "{during:?}");
        assert_eq!(f.counters().read_faults, 3);

        // Recovery: a fresh soft start, not a jump back to 3 N.
        let first = tick(&mut f, Vec3::X * 3.0);
        assert!(!f.fault_latched());
        assert_eq!(first, Vec3::ZERO, "ramp restarts from zero");
        let second = tick(&mut f, Vec3::X * 3.0);
        assert!(second.x > 0.0 && second.x < 0.1, "{second}");
        assert_eq!(f.counters().soft_starts, 2);
        for _ in 0..100 {
            tick(&mut f, Vec3::X * 3.0);
        }
        assert_eq!(f.output_force_n(), Vec3::X * 3.0);
    }

    #[test]
    fn zero_after_write_error() {
        let mut f = SafetyFilter::with_config(Probe::new(), no_ramp());
        f.open().unwrap();
        tick(&mut f, Vec3::ZERO);
        tick(&mut f, Vec3::Y);
        f.device_mut().fail_writes = 1;
        f.read().unwrap();
        assert!(f.write_force(Vec3::Y).is_err());
        assert!(f.fault_latched());
        assert_eq!(f.output_force_n(), Vec3::ZERO);
        assert_eq!(*f.device().written.last().unwrap(), Vec3::ZERO);
        assert_eq!(f.counters().write_faults, 1);
        // Latched: zero until a read succeeds.
        f.write_force(Vec3::Y).unwrap();
        assert_eq!(*f.device().written.last().unwrap(), Vec3::ZERO);
        assert_eq!(tick(&mut f, Vec3::Y), Vec3::Y);
    }

    #[test]
    fn boxed_dyn_device_works() {
        let dev: Box<dyn HapticDevice> = Box::new(Probe::new());
        let mut f: SafetyFilter = SafetyFilter::with_config(dev, no_ramp());
        f.open().unwrap();
        f.read().unwrap();
        f.write_force(Vec3::X).unwrap();
        f.read().unwrap();
        f.write_force(Vec3::X * 100.0).unwrap();
        assert!((f.output_force_n().length() - 5.0).abs() < 1e-5);
    }
}
