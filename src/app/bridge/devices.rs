//! The device panel's connect and disconnect, switching the running engine's device.

use super::*;

impl Bridge {
    /// Makes the device `spec` names and switches the running engine to it (the force limit
    /// asked for applies from its first tick); the old device is closed here.
    pub(super) fn connect(&mut self, what: &str, spec: &DeviceSpec, max_force_n: f32) {
        if let Err(e) = self.engine().force_limit().request(max_force_n) {
            self.fail(what, e.to_string());
            return;
        }
        let device = match (self.opener)(spec) {
            Ok(d) => d,
            Err(e) => {
                self.fail(what, format!("{spec}: {e}"));
                return;
            }
        };
        match self.engine().replace_device(device, SWAP_TIMEOUT) {
            Ok(report) => {
                let Some(connected) = report.connected else {
                    self.fail(
                        what,
                        format!("{spec}: the engine parked instead of connecting"),
                    );
                    return;
                };
                self.connected = true;
                self.spec = Some(spec.clone());
                let mut detail = format!("{} connected", connected.name);
                if let Some(replaced) = &report.replaced {
                    detail = format!("{detail}; {}", closed_detail(&replaced.name, &report.close));
                }
                self.device = connected;
                let _ = self.events.send(EngineEvent::Done {
                    what: what.into(),
                    detail,
                });
            }
            Err(e) => self.fail(what, format!("{spec}: {e}")),
        }
    }
}

/// "NAME closed", or the close error with it.
pub(super) fn closed_detail(
    name: &str,
    close: &Result<(), dynaclay_devices::DeviceError>,
) -> String {
    match close {
        Ok(()) => format!("{name} closed"),
        Err(e) => format!("{name} closed with an error: {e}"),
    }
}
