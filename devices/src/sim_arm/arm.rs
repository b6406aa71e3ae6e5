//! The simulated arm device: point-mass effector, spring–damper hand, scheduled faults.
//!
//! Guarantee: after `open`, `read` and `write_force` allocate nothing and do bounded work
//! (`substeps` spring–damper steps plus a scan of the fault list). Each `read` advances the
//! simulated clock by exactly `step_us` (except the first after `open`, which samples time
//! zero), so the arm's behaviour depends only on its configuration, its seed and the sequence
//! of calls, never on wall time.

use glam::Vec3;

use super::fault::{Fault, FaultKind};
use super::rng::SimRng;
use super::trajectory::{HandSample, Trajectory};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};

/// Settings of a [`SimulatedArm`]; `Default` gives a desktop-arm-like device at 1 kHz.
#[derive(Clone, Debug, PartialEq)]
pub struct SimArmConfig {
    /// What `info()` reports; `max_force_n` is also the motors' saturation and the workspace
    /// box the mechanical stops.
    pub info: DeviceInfo,
    /// Seed of the noise and drop generator.
    pub seed: u64,
    /// Simulated time advanced per `read`, microseconds.
    pub step_us: u64,
    /// Integration substeps per `read` (the written force is held across them).
    pub substeps: u32,
    /// Moving mass of the effector and the hand's grip, kilograms.
    pub effector_mass_kg: f32,
    /// Stiffness of the hand's grip on the effector, newtons per metre.
    pub hand_stiffness_n_per_m: f32,
    /// Damping of the hand's grip, newton-seconds per metre.
    pub hand_damping_n_s_per_m: f32,
    /// Viscous friction of the mechanism, newton-seconds per metre.
    pub friction_n_s_per_m: f32,
    /// Faults to inject, by simulated time.
    pub faults: Vec<Fault>,
}

impl SimArmConfig {
    /// The default device description: 3-DoF, 8 N, a 20 cm cube centred on the origin.
    #[must_use]
    pub fn default_info() -> DeviceInfo {
        DeviceInfo {
            name: "simulated arm".to_owned(),
            dof: 3,
            max_force_n: 8.0,
            max_stiffness_n_per_m: 3000.0,
            max_damping_n_s_per_m: 20.0,
            workspace_min_m: Vec3::splat(-0.1),
            workspace_max_m: Vec3::splat(0.1),
            has_orientation: false,
            has_force: true,
            button_count: 4,
            sample_rate_hz: 1000.0,
        }
    }
}

impl Default for SimArmConfig {
    fn default() -> Self {
        Self {
            info: Self::default_info(),
            seed: 0x5eed,
            step_us: 1000,
            substeps: 4,
            effector_mass_kg: 0.08,
            hand_stiffness_n_per_m: 300.0,
            // Close to critical damping of the grip (2·√(k·m) ≈ 9.8 N·s/m).
            hand_damping_n_s_per_m: 8.0,
            friction_n_s_per_m: 0.5,
            faults: Vec::new(),
        }
    }
}

/// What the arm has done since `open`; each injected fault shows up here.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SimArmCounters {
    /// Calls to `read` while open.
    pub reads: u64,
    /// Fresh samples delivered.
    pub samples: u64,
    /// Reads that returned the previous sample again (drop fault).
    pub dropped: u64,
    /// Fresh samples that reported a frozen position (freeze fault).
    pub frozen: u64,
    /// Fresh samples with noise added (noise fault).
    pub noisy: u64,
    /// Reads or writes refused with `Disconnected`.
    pub disconnected: u64,
    /// Reads or writes refused with `Timeout`.
    pub timeouts: u64,
    /// Forces accepted by `write_force`.
    pub writes: u64,
    /// Written forces the motors saturated (magnitude above `max_force_n`, or not finite).
    pub saturated: u64,
}

/// A closed-loop simulated haptic arm (see the module docs of [`crate::sim_arm`]).
///
/// Physics per substep `h`, with hand position `p_h(t)` and velocity `v_h(t)` from the
/// trajectory and the written force `F` held:
/// `m v̇ = k_h (p_h − x) + b_h (v_h − v) − b_f v + F`, integrated by semi-implicit Euler, then
/// `x` is kept inside the workspace box (a stop zeroes the velocity into it).
#[derive(Clone, Debug)]
pub struct SimulatedArm {
    config: SimArmConfig,
    trajectory: Trajectory,
    rng: SimRng,
    open: bool,
    /// The first read after `open` samples time zero without stepping.
    started: bool,
    time_us: u64,
    position_m: Vec3,
    velocity_m_per_s: Vec3,
    /// Force the motors output, newtons (zero while the link is down).
    motor_force_n: Vec3,
    /// Link fault in effect at the current time, if any.
    link_fault: Option<FaultKind>,
    /// Position reported while a freeze lasts.
    frozen_at_m: Option<Vec3>,
    sequence: u64,
    last_sample: Option<DeviceState>,
    counters: SimArmCounters,
}

impl SimulatedArm {
    /// An arm with `config` whose hand follows `trajectory`. It starts closed; the effector
    /// starts at rest at the trajectory's first position.
    #[must_use]
    pub fn new(config: SimArmConfig, trajectory: Trajectory) -> Self {
        let rng = SimRng::new(config.seed);
        let start = trajectory.sample(0.0).position_m;
        Self {
            config,
            trajectory,
            rng,
            open: false,
            started: false,
            time_us: 0,
            position_m: start,
            velocity_m_per_s: Vec3::ZERO,
            motor_force_n: Vec3::ZERO,
            link_fault: None,
            frozen_at_m: None,
            sequence: 0,
            last_sample: None,
            counters: SimArmCounters::default(),
        }
    }

    /// An arm with the default configuration following `trajectory`.
    #[must_use]
    pub fn with_trajectory(trajectory: Trajectory) -> Self {
        Self::new(SimArmConfig::default(), trajectory)
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &SimArmConfig {
        &self.config
    }

    /// The hand's script.
    #[must_use]
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }

    /// Simulated time since `open`, microseconds.
    #[must_use]
    pub fn time_us(&self) -> u64 {
        self.time_us
    }

    /// True (noise-free, unfrozen) effector position, metres.
    #[must_use]
    pub fn effector_position_m(&self) -> Vec3 {
        self.position_m
    }

    /// True effector velocity, metres per second.
    #[must_use]
    pub fn effector_velocity_m_per_s(&self) -> Vec3 {
        self.velocity_m_per_s
    }

    /// Where the scripted hand is now.
    #[must_use]
    pub fn hand(&self) -> HandSample {
        self.trajectory.sample(self.time_us as f64 / 1e6)
    }

    /// Force the motors are producing, newtons (zero while the link is down).
    #[must_use]
    pub fn motor_force_n(&self) -> Vec3 {
        self.motor_force_n
    }

    /// Counters since `open`.
    #[must_use]
    pub fn counters(&self) -> SimArmCounters {
        self.counters
    }

    fn reset(&mut self) {
        *self = Self::new(self.config.clone(), self.trajectory.clone());
    }

    /// Advances the physics by one read step with the motor force held.
    fn step(&mut self) {
        let substeps = self.config.substeps.max(1);
        let h_us = self.config.step_us as f64 / f64::from(substeps);
        let h_s = (h_us * 1e-6) as f32;
        let inv_mass = 1.0 / self.config.effector_mass_kg.max(1e-6);
        let (lo, hi) = (
            self.config.info.workspace_min_m,
            self.config.info.workspace_max_m,
        );
        for k in 1..=substeps {
            let t_s = (self.time_us as f64 + h_us * f64::from(k)) / 1e6;
            let hand = self.trajectory.sample(t_s);
            let force = (hand.position_m - self.position_m) * self.config.hand_stiffness_n_per_m
                + (hand.velocity_m_per_s - self.velocity_m_per_s)
                    * self.config.hand_damping_n_s_per_m
                - self.velocity_m_per_s * self.config.friction_n_s_per_m
                + self.motor_force_n;
            self.velocity_m_per_s += force * (inv_mass * h_s);
            self.position_m += self.velocity_m_per_s * h_s;
            // Mechanical stops: clamp, and kill velocity pointing further out.
            for axis in 0..3 {
                if self.position_m[axis] < lo[axis] {
                    self.position_m[axis] = lo[axis];
                    self.velocity_m_per_s[axis] = self.velocity_m_per_s[axis].max(0.0);
                } else if self.position_m[axis] > hi[axis] {
                    self.position_m[axis] = hi[axis];
                    self.velocity_m_per_s[axis] = self.velocity_m_per_s[axis].min(0.0);
                }
            }
        }
        self.time_us += self.config.step_us;
    }

    /// Active faults at the current time, folded: (link, freeze, noise std, drop probability).
    fn active_faults(&self) -> (Option<FaultKind>, bool, f32, f32) {
        let mut link = None;
        let mut freeze = false;
        let mut noise_std_m = 0.0_f32;
        let mut drop_p = 0.0_f32;
        for fault in self
            .config
            .faults
            .iter()
            .filter(|f| f.active_at_us(self.time_us))
        {
            match fault.kind {
                FaultKind::Disconnect => link = Some(FaultKind::Disconnect),
                FaultKind::Stall => {
                    if link.is_none() {
                        link = Some(FaultKind::Stall);
                    }
                }
                FaultKind::Freeze => freeze = true,
                FaultKind::Noise { std_m } => noise_std_m = noise_std_m.max(std_m),
                FaultKind::Drop { probability } => drop_p = drop_p.max(probability),
            }
        }
        (link, freeze, noise_std_m, drop_p)
    }

    fn link_error(&mut self) -> Option<DeviceError> {
        match self.link_fault {
            Some(FaultKind::Disconnect) => {
                self.counters.disconnected += 1;
                Some(DeviceError::Disconnected)
            }
            Some(_) => {
                self.counters.timeouts += 1;
                Some(DeviceError::Timeout {
                    waited_us: self.config.step_us,
                })
            }
            None => None,
        }
    }
}

impl HapticDevice for SimulatedArm {
    /// The configured description; an arm whose trajectory turns the hand senses orientation.
    fn info(&self) -> DeviceInfo {
        let mut info = self.config.info.clone();
        info.has_orientation |= self.trajectory.has_orientation();
        if info.has_orientation {
            info.dof = info.dof.max(6);
        }
        info
    }

    /// Opens the arm at simulated time zero, effector at rest at the script's start and the
    /// generator reseeded, so every open replays the same run. Opening an open arm is a no-op.
    fn open(&mut self) -> Result<(), DeviceError> {
        if !self.open {
            self.reset();
            self.open = true;
        }
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        self.motor_force_n = Vec3::ZERO;
        self.open = false;
        Ok(())
    }

    fn is_open(&self) -> bool {
        self.open
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        if !self.open {
            return Err(DeviceError::NotOpen);
        }
        if self.started {
            self.step();
        } else {
            self.started = true;
        }
        self.counters.reads += 1;
        let (link, freeze, noise_std_m, drop_p) = self.active_faults();
        self.link_fault = link;
        if let Some(err) = self.link_error() {
            // The firmware's watchdog drops the motor command while nobody talks to it.
            self.motor_force_n = Vec3::ZERO;
            return Err(err);
        }
        if drop_p > 0.0
            && self.rng.chance(drop_p)
            && let Some(previous) = self.last_sample
        {
            // The device produced a sample; the host missed it.
            self.sequence += 1;
            self.counters.dropped += 1;
            return Ok(previous);
        }

        let hand = self.trajectory.sample(self.time_us as f64 / 1e6);
        let (mut position_m, velocity_m_per_s) = if freeze {
            self.counters.frozen += 1;
            (*self.frozen_at_m.get_or_insert(self.position_m), Vec3::ZERO)
        } else {
            self.frozen_at_m = None;
            (self.position_m, self.velocity_m_per_s)
        };
        if noise_std_m > 0.0 {
            self.counters.noisy += 1;
            position_m += Vec3::new(
                self.rng.next_normal(),
                self.rng.next_normal(),
                self.rng.next_normal(),
            ) * noise_std_m;
        }
        self.sequence += 1;
        self.counters.samples += 1;
        let sample = DeviceState {
            position_m,
            // The grip holds the handle's rotation rigidly: the effector turns with the hand.
            orientation: hand.orientation,
            velocity_m_per_s,
            buttons: hand.buttons,
            timestamp_us: self.time_us,
            sequence: self.sequence,
        };
        self.last_sample = Some(sample);
        Ok(sample)
    }

    /// Holds `force_n` on the motors until the next write, saturated at `max_force_n`
    /// (a non-finite force is treated as zero, as a motor driver would).
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        if !self.open {
            return Err(DeviceError::NotOpen);
        }
        if let Some(err) = self.link_error() {
            self.motor_force_n = Vec3::ZERO;
            return Err(err);
        }
        self.counters.writes += 1;
        let max_n = self.config.info.max_force_n;
        self.motor_force_n = if !force_n.is_finite() {
            self.counters.saturated += 1;
            Vec3::ZERO
        } else if force_n.length() > max_n {
            self.counters.saturated += 1;
            force_n.clamp_length_max(max_n)
        } else {
            force_n
        };
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim_arm::{Interpolation, Waypoint};

    /// Hand moves from the origin down to y = −2 cm in 0.5 s, with button 0 held after 0.1 s.
    fn press_down() -> Trajectory {
        Trajectory::new(
            vec![
                Waypoint::new(0.0, Vec3::ZERO),
                Waypoint::with_buttons(0.1, Vec3::ZERO, 1),
                Waypoint::with_buttons(0.5, Vec3::new(0.0, -0.02, 0.0), 1),
            ],
            Interpolation::Smooth,
        )
        .unwrap()
    }

    /// A virtual wall at y = 0 (solid below), stiffness `k`.
    fn wall_force(k: f32, s: &DeviceState) -> Vec3 {
        Vec3::new(0.0, k * (-s.position_m.y).max(0.0), 0.0)
    }

    fn run(arm: &mut SimulatedArm, ticks: usize, k: f32) -> Vec<Result<DeviceState, DeviceError>> {
        arm.open().unwrap();
        (0..ticks)
            .map(|_| {
                let r = arm.read();
                let f = r.as_ref().map_or(Vec3::ZERO, |s| wall_force(k, s));
                let _ = arm.write_force(f);
                r
            })
            .collect()
    }

    fn noisy_dropping_config(seed: u64) -> SimArmConfig {
        SimArmConfig {
            seed,
            faults: vec![
                Fault::new(0.0, 10.0, FaultKind::Noise { std_m: 1e-4 }),
                Fault::new(0.2, 0.3, FaultKind::Drop { probability: 0.2 }),
            ],
            ..SimArmConfig::default()
        }
    }

    #[test]
    fn deterministic_for_a_seed() {
        let a = run(
            &mut SimulatedArm::new(noisy_dropping_config(9), press_down()),
            800,
            2000.0,
        );
        let b = run(
            &mut SimulatedArm::new(noisy_dropping_config(9), press_down()),
            800,
            2000.0,
        );
        let c = run(
            &mut SimulatedArm::new(noisy_dropping_config(10), press_down()),
            800,
            2000.0,
        );
        assert_eq!(a, b);
        assert_ne!(a, c);
        // Reopening replays the same run.
        let mut arm = SimulatedArm::new(noisy_dropping_config(9), press_down());
        let first = run(&mut arm, 800, 2000.0);
        arm.close().unwrap();
        assert_eq!(first, run(&mut arm, 800, 2000.0));
    }

    #[test]
    fn clock_advances_one_step_per_read() {
        let mut arm = SimulatedArm::with_trajectory(press_down());
        assert_eq!(arm.read(), Err(DeviceError::NotOpen));
        assert_eq!(arm.write_force(Vec3::ZERO), Err(DeviceError::NotOpen));
        let samples = run(&mut arm, 5, 0.0);
        let stamps: Vec<u64> = samples
            .iter()
            .map(|s| s.as_ref().unwrap().timestamp_us)
            .collect();
        assert_eq!(stamps, [0, 1000, 2000, 3000, 4000]);
        let seqs: Vec<u64> = samples
            .iter()
            .map(|s| s.as_ref().unwrap().sequence)
            .collect();
        assert_eq!(seqs, [1, 2, 3, 4, 5]);
    }

    #[test]
    fn free_hand_reaches_its_target_and_buttons_follow_script() {
        let mut arm = SimulatedArm::with_trajectory(press_down());
        let samples = run(&mut arm, 1500, 0.0);
        let last = samples.last().unwrap().as_ref().unwrap();
        assert!(
            (last.position_m.y + 0.02).abs() < 2e-4,
            "{}",
            last.position_m
        );
        assert!(!samples[50].as_ref().unwrap().button(0));
        assert!(samples[150].as_ref().unwrap().button(0));
    }

    #[test]
    fn stiff_wall_stops_the_effector_short_of_the_hand() {
        let k = 2000.0;
        let mut arm = SimulatedArm::with_trajectory(press_down());
        let samples = run(&mut arm, 1500, k);
        let last = samples.last().unwrap().as_ref().unwrap();
        // Static balance of grip and wall: x = k_h·h / (k_h + k_w).
        let expected_y = 300.0 * -0.02 / (300.0 + k);
        assert!(
            (last.position_m.y - expected_y).abs() < 2e-4,
            "{} vs {expected_y}",
            last.position_m.y
        );
        assert!(arm.hand().position_m.y < -0.0199);
        assert!(last.velocity_m_per_s.length() < 1e-3);
        // The rendered force balances the hand pulling down.
        let f = wall_force(k, last);
        assert!(
            (f.y - 300.0 * (last.position_m.y + 0.02)).abs() < 0.1,
            "{f}"
        );
        assert!(
            samples
                .iter()
                .all(|s| s.as_ref().unwrap().position_m.is_finite())
        );
    }

    #[test]
    fn mechanical_stops_bound_the_effector() {
        let far = Trajectory::new(
            vec![
                Waypoint::new(0.0, Vec3::ZERO),
                Waypoint::new(0.2, Vec3::new(0.5, 0.0, -0.5)),
            ],
            Interpolation::Linear,
        )
        .unwrap();
        let mut arm = SimulatedArm::with_trajectory(far);
        for s in run(&mut arm, 600, 0.0) {
            let p = s.unwrap().position_m;
            assert!(p.x <= 0.1 && p.z >= -0.1, "{p}");
        }
        assert_eq!(arm.effector_position_m().x, 0.1);
    }

    #[test]
    fn disconnect_fault_refuses_reads_and_writes_then_recovers() {
        let config = SimArmConfig {
            faults: vec![Fault::new(0.1, 0.05, FaultKind::Disconnect)],
            ..SimArmConfig::default()
        };
        let mut arm = SimulatedArm::new(config, press_down());
        arm.open().unwrap();
        let mut errors = 0;
        for i in 0..300 {
            let r = arm.read();
            let t_ms = i as f64;
            if (100.0..150.0).contains(&t_ms) {
                assert_eq!(r, Err(DeviceError::Disconnected), "tick {i}");
                assert_eq!(arm.write_force(Vec3::Y), Err(DeviceError::Disconnected));
                assert_eq!(arm.motor_force_n(), Vec3::ZERO);
                errors += 1;
            } else {
                assert!(r.is_ok(), "tick {i}: {r:?}");
                arm.write_force(Vec3::Y).unwrap();
            }
        }
        assert_eq!(errors, 50);
        assert_eq!(arm.counters().disconnected, 100);
        assert_eq!(arm.motor_force_n(), Vec3::Y);
    }

    #[test]
    fn stall_fault_times_out() {
        let config = SimArmConfig {
            faults: vec![Fault::new(0.05, 0.01, FaultKind::Stall)],
            ..SimArmConfig::default()
        };
        let results = run(&mut SimulatedArm::new(config, press_down()), 100, 0.0);
        let timeouts = results
            .iter()
            .filter(|r| matches!(r, Err(DeviceError::Timeout { waited_us: 1000 })))
            .count();
        assert_eq!(timeouts, 10);
        assert!(results[49].is_ok() && results[60].is_ok());
    }

    #[test]
    fn freeze_fault_repeats_position_with_fresh_sequence() {
        let config = SimArmConfig {
            faults: vec![Fault::new(0.2, 0.1, FaultKind::Freeze)],
            ..SimArmConfig::default()
        };
        let mut arm = SimulatedArm::new(config, press_down());
        let samples: Vec<DeviceState> = run(&mut arm, 400, 0.0)
            .into_iter()
            .map(Result::unwrap)
            .collect();
        let frozen = &samples[200..300];
        assert!(frozen.iter().all(|s| s.position_m == frozen[0].position_m));
        assert!(frozen.iter().all(|s| s.velocity_m_per_s == Vec3::ZERO));
        assert!(
            frozen
                .windows(2)
                .all(|w| w[1].sequence == w[0].sequence + 1)
        );
        // The hand kept moving underneath, so the position jumps when the freeze ends.
        assert!((samples[300].position_m - frozen[0].position_m).length() > 1e-3);
        assert_eq!(arm.counters().frozen, 100);
    }

    #[test]
    fn noise_fault_perturbs_reported_position_only() {
        let config = SimArmConfig {
            faults: vec![Fault::new(0.0, 1.0, FaultKind::Noise { std_m: 1e-3 })],
            ..SimArmConfig::default()
        };
        let mut arm = SimulatedArm::new(config, Trajectory::hold(Vec3::ZERO));
        let samples: Vec<DeviceState> = run(&mut arm, 2000, 0.0)
            .into_iter()
            .map(Result::unwrap)
            .collect();
        let noisy = &samples[..1000];
        let rms = (noisy.iter().map(|s| s.position_m.x.powi(2)).sum::<f32>() / 1000.0).sqrt();
        assert!((rms - 1e-3).abs() < 1.5e-4, "rms {rms}");
        assert!(samples[1000..].iter().all(|s| s.position_m == Vec3::ZERO));
        assert_eq!(arm.effector_position_m(), Vec3::ZERO, "physics untouched");
        assert_eq!(arm.counters().noisy, 1000);
    }

    #[test]
    fn drop_fault_repeats_samples_and_shows_gaps() {
        let config = SimArmConfig {
            faults: vec![Fault::new(0.0, 1.0, FaultKind::Drop { probability: 0.3 })],
            ..SimArmConfig::default()
        };
        let mut arm = SimulatedArm::new(config, press_down());
        let samples: Vec<DeviceState> = run(&mut arm, 1000, 0.0)
            .into_iter()
            .map(Result::unwrap)
            .collect();
        let repeats = samples.windows(2).filter(|w| w[1] == w[0]).count();
        let gaps = samples
            .windows(2)
            .filter(|w| w[1].sequence > w[0].sequence + 1)
            .count();
        let dropped = arm.counters().dropped as usize;
        assert!((200..400).contains(&dropped), "{dropped}");
        assert_eq!(repeats, dropped);
        assert!(gaps > 0);
        assert_eq!(arm.counters().samples as usize + dropped, 1000);
        assert!(samples.windows(2).all(|w| w[1].sequence >= w[0].sequence));
    }

    #[test]
    fn motors_saturate_at_max_force() {
        let mut arm = SimulatedArm::with_trajectory(press_down());
        arm.open().unwrap();
        arm.read().unwrap();
        arm.write_force(Vec3::X * 100.0).unwrap();
        assert!((arm.motor_force_n().length() - 8.0).abs() < 1e-5);
        arm.write_force(Vec3::splat(f32::NAN)).unwrap();
        assert_eq!(arm.motor_force_n(), Vec3::ZERO);
        assert_eq!(arm.counters().saturated, 2);
    }
}
