//! Replacing the device under the running haptic loop: a newly opened device goes in, the old
//! one comes back out to be closed, and the loop never stops ticking.
//!
//! Guarantee: the haptic side ([`DeviceSwapPort::take`], [`DeviceSwapPort::retire`]) is
//! wait-free and allocation-free. It uses two crossbeam array channels of capacity one, only
//! through `try_recv` and `try_send`, and the requesting side polls rather than blocks, so no
//! send from the tick ever has a parked thread to wake. Opening the new device and closing the
//! old one (serial handshakes, firmware loads, joining driver threads) happen on the
//! requesting thread, never on the haptic thread.

use std::time::{Duration, Instant};

use crossbeam::channel::{Receiver, Sender, TryRecvError, bounded};
use dynaclay_devices::{DeviceError, DeviceInfo, DeviceState, HapticDevice, SafetyFilter};
use glam::Vec3;

use super::workspace::WorkspaceMap;

/// A device ready for the haptic loop: opened behind its own safety filter, with the map from
/// its workspace to the field. `connected: false` parks the loop: it reads nothing, sends
/// nothing and publishes an idle tool sample until the next handover.
pub struct DeviceHandover {
    /// The device behind its safety filter (opened, unless this handover parks the loop).
    pub device: SafetyFilter<Box<dyn HapticDevice>>,
    /// Device workspace to field coordinates for this device.
    pub map: WorkspaceMap,
    /// Whether the loop should drive this device (false: no device connected).
    pub connected: bool,
}

impl std::fmt::Debug for DeviceHandover {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DeviceHandover")
            .field("device", &self.device.device().info().name)
            .field("map", &self.map)
            .field("connected", &self.connected)
            .finish()
    }
}

impl DeviceHandover {
    /// The handover that parks the loop with no device.
    #[must_use]
    pub fn parked(map: WorkspaceMap) -> Self {
        Self {
            device: SafetyFilter::new(Box::new(NoDevice)),
            map,
            connected: false,
        }
    }
}

/// The haptic loop's end: takes a waiting handover and returns the one it replaces.
pub struct DeviceSwapPort {
    incoming: Receiver<DeviceHandover>,
    retired: Sender<DeviceHandover>,
}

impl DeviceSwapPort {
    /// The waiting handover, if any, but only while the retired slot has room, so that
    /// [`DeviceSwapPort::retire`] of the device it replaces cannot fail (the old device must
    /// never be dropped, and so closed, on the haptic thread).
    pub fn take(&self) -> Option<DeviceHandover> {
        if self.retired.is_full() {
            return None;
        }
        self.incoming.try_recv().ok()
    }

    /// Sends a replaced device back to the requester. Returns it if the slot is full, which
    /// [`DeviceSwapPort::take`] rules out for this port's only sender.
    ///
    /// # Errors
    /// The handover itself, when the slot is full or the requester is gone.
    #[allow(clippy::result_large_err)] // the error hands the device back rather than drop it
    pub fn retire(&self, old: DeviceHandover) -> Result<(), DeviceHandover> {
        self.retired.try_send(old).map_err(|e| e.into_inner())
    }
}

/// The requesting end (the engine's owner: CLI, GUI bridge, tests).
pub struct DeviceSwapRequest {
    incoming: Sender<DeviceHandover>,
    /// A second receiver on the incoming slot, to withdraw a handover the loop never took.
    withdraw: Receiver<DeviceHandover>,
    retired: Receiver<DeviceHandover>,
}

/// How often the requester looks for the retired device. Polling, not a blocking receive, so
/// the haptic tick's send never has a sleeping receiver to wake.
const POLL: Duration = Duration::from_millis(1);

/// Why a swap did not happen.
pub enum SwapFailure {
    /// The loop did not take the new device within the timeout (it is stopped or stalled);
    /// the new device is handed back, still open.
    NotTaken(Box<DeviceHandover>),
    /// A previous swap's device is still waiting in the slot.
    Busy(Box<DeviceHandover>),
    /// The loop took the new device but never returned the old one (it stopped mid-swap).
    Lost,
}

impl std::fmt::Debug for SwapFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::NotTaken(_) => "NotTaken",
            Self::Busy(_) => "Busy",
            Self::Lost => "Lost",
        })
    }
}

impl DeviceSwapRequest {
    /// Offers `new` to the haptic loop and waits up to `timeout` for the device it replaces.
    ///
    /// # Errors
    /// [`SwapFailure`], which hands `new` back so the caller can close it.
    pub fn swap(
        &self,
        new: DeviceHandover,
        timeout: Duration,
    ) -> Result<DeviceHandover, SwapFailure> {
        if let Err(e) = self.incoming.try_send(new) {
            return Err(SwapFailure::Busy(Box::new(e.into_inner())));
        }
        let deadline = Instant::now() + timeout;
        loop {
            match self.retired.try_recv() {
                Ok(old) => return Ok(old),
                Err(TryRecvError::Disconnected) => break,
                Err(TryRecvError::Empty) if Instant::now() >= deadline => break,
                Err(TryRecvError::Empty) => std::thread::sleep(POLL),
            }
        }
        match self.withdraw.try_recv() {
            Ok(new) => Err(SwapFailure::NotTaken(Box::new(new))),
            // Taken between the last poll and the withdrawal: the old one is on its way.
            Err(_) => {
                let late = Instant::now() + Duration::from_millis(100);
                while Instant::now() < late {
                    if let Ok(old) = self.retired.try_recv() {
                        return Ok(old);
                    }
                    std::thread::sleep(POLL);
                }
                Err(SwapFailure::Lost)
            }
        }
    }
}

/// A connected pair of ends.
#[must_use]
pub fn device_swap_channel() -> (DeviceSwapRequest, DeviceSwapPort) {
    let (in_tx, in_rx) = bounded(1);
    let (out_tx, out_rx) = bounded(1);
    (
        DeviceSwapRequest {
            incoming: in_tx,
            withdraw: in_rx.clone(),
            retired: out_rx,
        },
        DeviceSwapPort {
            incoming: in_rx,
            retired: out_tx,
        },
    )
}

/// The empty device slot: no position, no force. The haptic loop never reads it (a parked
/// handover is not driven); it exists so the slot always holds a device to close.
struct NoDevice;

impl HapticDevice for NoDevice {
    fn info(&self) -> DeviceInfo {
        DeviceInfo {
            name: "no device".into(),
            dof: 0,
            max_force_n: 0.0,
            max_stiffness_n_per_m: 0.0,
            max_damping_n_s_per_m: 0.0,
            workspace_min_m: Vec3::ZERO,
            workspace_max_m: Vec3::ZERO,
            has_orientation: false,
            has_force: false,
            button_count: 0,
            sample_rate_hz: 0.0,
        }
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        Ok(())
    }

    fn is_open(&self) -> bool {
        false
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        Err(DeviceError::NotOpen)
    }

    fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynaclay_devices::{SimArmConfig, SimulatedArm};

    fn map() -> WorkspaceMap {
        WorkspaceMap::fitting(
            Vec3::splat(-0.1),
            Vec3::splat(0.1),
            Vec3::ZERO,
            Vec3::ONE,
            30.0,
        )
    }

    fn arm_handover() -> DeviceHandover {
        let arm = SimulatedArm::new(
            SimArmConfig::default(),
            dynaclay_devices::Trajectory::hold(Vec3::ZERO),
        );
        DeviceHandover {
            device: SafetyFilter::new(Box::new(arm)),
            map: map(),
            connected: true,
        }
    }

    #[test]
    fn the_port_takes_the_new_device_and_the_requester_gets_the_old_one() {
        let (request, port) = device_swap_channel();
        let ticker = std::thread::spawn(move || {
            // A stand-in haptic loop: its current device is parked until the swap.
            let mut current = DeviceHandover::parked(map());
            for _ in 0..2000 {
                if let Some(new) = port.take() {
                    let old = std::mem::replace(&mut current, new);
                    assert!(port.retire(old).is_ok(), "take guaranteed room");
                }
                std::thread::sleep(Duration::from_micros(200));
            }
            current.connected
        });
        let old = request
            .swap(arm_handover(), Duration::from_secs(5))
            .expect("swapped");
        assert!(!old.connected, "the parked slot came back");
        assert!(ticker.join().unwrap(), "the loop drives the new device");
    }

    #[test]
    fn a_loop_that_never_takes_it_hands_the_new_device_back() {
        let (request, port) = device_swap_channel();
        let result = request.swap(arm_handover(), Duration::from_millis(20));
        match result {
            Err(SwapFailure::NotTaken(h)) => assert!(h.connected, "the offered device"),
            other => panic!("expected NotTaken, got {other:?}"),
        }
        // The slot is empty again: a later swap can be offered.
        assert!(port.take().is_none());
    }

    #[test]
    fn take_waits_while_the_retired_slot_is_full() {
        let (_request, port) = device_swap_channel();
        port.retire(DeviceHandover::parked(map())).ok().unwrap();
        // Room for exactly one retired device: take must refuse so retire cannot fail.
        assert!(port.retire(DeviceHandover::parked(map())).is_err());
        assert!(port.take().is_none());
    }
}
