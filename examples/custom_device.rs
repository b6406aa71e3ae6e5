//! A custom haptic device: implement [`HapticDevice`] and the engine drives it as it drives a
//! real arm.
//!
//! `Poker` is a scripted stylus: with its button held it goes down into the top of the
//! default block at a steady 2 cm/s for half a second and comes back up. The lockstep engine
//! reads it once a tick, sculpts with the default tool, and writes the reaction force back;
//! the example prints what the stylus felt. A driver for a new arm has the same shape: `read`
//! returns the newest sample without blocking, `write_force` sends one force command, and
//! `close` leaves the arm at zero force. Run with
//!
//! ```text
//! cargo run --release --example custom_device
//! ```

use std::error::Error;

use dynaclay::engine::{EngineConfig, HeadlessSink, Lockstep, build_clay};
use dynaclay::io::ClaySpec;
use dynaclay_devices::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use glam::Vec3;

/// A stylus on a scripted path: down at `speed_m_per_s` from `start_m` for `down_s`, then up
/// again, button 0 held throughout. One sample per millisecond of its own clock.
struct Poker {
    start_m: Vec3,
    speed_m_per_s: f32,
    down_s: f32,
    open: bool,
    sequence: u64,
    /// The forces the engine sent, newtons (one per tick).
    felt_n: Vec<Vec3>,
}

impl Poker {
    fn position_at(&self, t_s: f32) -> Vec3 {
        // Down, then back up along the same line.
        let depth_s = if t_s < self.down_s {
            t_s
        } else {
            (2.0 * self.down_s - t_s).max(0.0)
        };
        self.start_m - Vec3::Y * self.speed_m_per_s * depth_s
    }
}

impl HapticDevice for Poker {
    fn info(&self) -> DeviceInfo {
        DeviceInfo {
            name: "scripted poker".into(),
            dof: 3,
            max_force_n: 3.0,
            max_stiffness_n_per_m: 1000.0,
            max_damping_n_s_per_m: 5.0,
            workspace_min_m: Vec3::splat(-0.08),
            workspace_max_m: Vec3::splat(0.08),
            has_orientation: false,
            has_force: true,
            button_count: 1,
            sample_rate_hz: 1000.0,
        }
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        self.open = true;
        self.sequence = 0;
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        // A real driver sends zero force before letting go of the arm.
        self.write_force(Vec3::ZERO)?;
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
        self.sequence += 1;
        let t_s = self.sequence as f32 * 1e-3;
        let velocity = (self.position_at(t_s) - self.position_at(t_s - 1e-3)) * 1e3;
        Ok(DeviceState {
            position_m: self.position_at(t_s),
            orientation: None,
            velocity_m_per_s: velocity,
            buttons: 1,
            timestamp_us: self.sequence * 1000,
            sequence: self.sequence,
        })
    }

    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        if !self.open {
            return Err(DeviceError::NotOpen);
        }
        self.felt_n.push(force_n);
        Ok(())
    }
}

fn main() {
    if let Err(e) = run() {
        eprintln!("custom_device: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn Error>> {
    let clay = build_clay(&ClaySpec::default())?;
    let probe = Poker {
        start_m: Vec3::ZERO,
        speed_m_per_s: 0.02,
        down_s: 0.5,
        open: false,
        sequence: 0,
        felt_n: Vec::new(),
    };
    let mut config = EngineConfig::for_field(&clay, &probe.info());
    config.haptic_rt_priority = None;
    // Start a little above the middle of the block's top face: the block fills the middle
    // half of the lattice, and the map puts the lattice in the device's workspace.
    let (lo, hi) = clay.support();
    let top_middle = (0..200)
        .map(|i| lo + (hi - lo) * Vec3::new(0.5, 1.0 - i as f32 / 200.0, 0.5))
        .find(|&p| clay.is_inside(p))
        .ok_or("the block has no top")?;
    let start_m = config.map.to_device(top_middle) + Vec3::Y * 0.002;
    let device = Box::new(Poker { start_m, ..probe });

    let mut run = Lockstep::new(&config, clay, device, Box::new(HeadlessSink::default()), 16)?;
    println!("  time    tip y (field)   force felt (N)");
    for tick in 1..=1200u32 {
        run.step();
        if tick % 100 == 0 {
            let sample = run.latest_tool();
            println!(
                "{:>5} ms  {:>12.4}   {:>10.3}",
                tick,
                sample.tip_fu.y,
                sample.device_force_n.length()
            );
        }
    }
    let report = run.finish()?;
    println!(
        "the safety filter clamped {} forces; the device closed {}",
        report.safety.clamped,
        if report.device_close_error.is_none() {
            "cleanly"
        } else {
            "with an error"
        }
    );
    Ok(())
}
