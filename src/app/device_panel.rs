//! The device panel: choose a device spec (typed, or picked from a scan of what is plugged
//! in), connect and disconnect, see its status, and set the force limit and the haptic gain.
//!
//! Specs are parsed by the devices crate's own parser, so the panel accepts exactly what
//! `--device` accepts and shows the same error text.
//!
//! The device in use has one source: the engine's [`DeviceStatus`]. The status line names it,
//! and the list starts on it (and returns to it whenever the engine switches), marked
//! "in use"; choosing another entry only prepares the next Connect.

use dynaclay_devices::enumerate::{self, Access, Connected};
use dynaclay_devices::spec::{DeviceSpec, SpecError};

use super::view::{DeviceLinkState, DeviceStatus};

/// The kinds of spec, as the first word of the spec string.
pub const SPEC_KINDS: [(&str, &str); 7] = [
    ("sim", "simulated arm"),
    ("hid", "HID arm (optional profile)"),
    ("serial", "serial arm (port, optional :profile)"),
    ("falcon", "Novint Falcon (port)"),
    ("spacemouse", "SpaceMouse (pose only)"),
    ("replay", "replay (recording file)"),
    ("mouse", "mouse (the window's pointer)"),
];

/// What the user asked the panel to do.
#[derive(Clone, Debug, PartialEq)]
pub enum DeviceAction {
    Connect { spec: DeviceSpec, max_force_n: f32 },
    Disconnect,
    SetMaxForce { max_force_n: f32 },
    SetHapticGain { gain: f32 },
}

/// The panel's state.
#[derive(Clone, Debug, PartialEq)]
pub struct DevicePanel {
    /// Index into [`SPEC_KINDS`].
    pub kind: usize,
    /// What follows `kind:` in the spec (port, profile, file); may be empty.
    pub argument: String,
    /// Force limit asked for, newtons.
    pub max_force_n: f32,
    /// How strongly sculpting is felt (shown in the material panel too).
    pub haptic_gain: f32,
    /// Result of the last scan (`None`: not scanned yet).
    pub scanned: Option<(Vec<Connected>, Vec<String>)>,
    /// The engine's device last taken into the list (see [`DevicePanel::follow`]).
    in_use_seen: Option<DeviceSpec>,
}

impl Default for DevicePanel {
    fn default() -> Self {
        Self {
            kind: 0,
            argument: String::new(),
            max_force_n: 3.0,
            haptic_gain: 1.0,
            scanned: None,
            in_use_seen: None,
        }
    }
}

/// Largest force limit the slider offers, newtons (drivers clamp further to their own maximum).
pub const MAX_FORCE_LIMIT_N: f32 = 20.0;

/// The haptic gain slider, the same in the device and material panels: how strongly the
/// sculpting reaction is felt, 1 meaning that a 5 mm press into the fresh clay feels 2 N (the
/// device's force limit still caps it). True when the user moved it.
pub fn haptic_gain_slider(ui: &mut egui::Ui, gain: &mut f32) -> bool {
    ui.add(egui::Slider::new(gain, 0.0..=crate::engine::MAX_HAPTIC_GAIN).text("Haptic gain"))
        .on_hover_text("1: a 5 mm press into the fresh clay feels 2 N")
        .changed()
}

impl DevicePanel {
    /// The spec string as typed: `kind` or `kind:argument`.
    #[must_use]
    pub fn spec_text(&self) -> String {
        let kind = SPEC_KINDS.get(self.kind).map_or("sim", |k| k.0);
        let arg = self.argument.trim();
        if arg.is_empty() {
            kind.to_string()
        } else {
            format!("{kind}:{arg}")
        }
    }

    /// The parsed spec.
    ///
    /// # Errors
    /// The parser's [`SpecError`], quoting the text.
    pub fn spec(&self) -> Result<DeviceSpec, SpecError> {
        self.spec_text().parse()
    }

    /// Fills kind and argument from a spec string (for example one found by a scan).
    pub fn set_spec_text(&mut self, text: &str) {
        let (_, arg) = text.split_once(':').unwrap_or((text, ""));
        if let Some(i) = kind_index(text) {
            self.kind = i;
            self.argument = arg.to_string();
        }
    }

    /// Puts the list on the engine's device when the engine reports a device it had not
    /// reported before (at start and after each switch); otherwise leaves the user's choice.
    pub fn follow(&mut self, status: &DeviceStatus) {
        if status.spec.is_some() && status.spec != self.in_use_seen {
            self.in_use_seen.clone_from(&status.spec);
            if let Some(spec) = &status.spec {
                self.set_spec_text(&spec.to_string());
            }
        }
    }

    /// Draws the panel; returns what the user asked for, if anything.
    pub fn ui(&mut self, ui: &mut egui::Ui, status: &DeviceStatus) -> Option<DeviceAction> {
        self.follow(status);
        let mut action = None;
        ui.horizontal_wrapped(|ui| {
            ui.label("Status:");
            let colour = match status.state {
                DeviceLinkState::Connected => egui::Color32::from_rgb(90, 200, 90),
                DeviceLinkState::Connecting => ui.visuals().warn_fg_color,
                DeviceLinkState::Faulted => ui.visuals().error_fg_color,
                DeviceLinkState::Disconnected => ui.visuals().weak_text_color(),
            };
            ui.colored_label(colour, status.state.name());
            if !status.name.is_empty() {
                ui.label(&status.name);
            }
        });
        if let Some(spec) = &status.spec {
            ui.weak(format!("in use: --device {spec}"));
        }
        if status.state == DeviceLinkState::Connected {
            ui.label(format!(
                "force limit {:.2} N (device max {:.2} N){}, peak {:.2} N",
                status.max_force_n,
                status.device_max_force_n,
                if status.has_force {
                    ""
                } else {
                    " (no force output)"
                },
                status.peak_force_n
            ));
        }
        let in_use_kind = status
            .spec
            .as_ref()
            .and_then(|s| kind_index(&s.to_string()));
        let entry = |i: usize| {
            let label = SPEC_KINDS.get(i).map_or("sim", |k| k.1);
            if Some(i) == in_use_kind {
                format!("{label} (in use)")
            } else {
                label.to_owned()
            }
        };
        // The name above the list, and the list one line across the panel, so a long entry
        // neither widens the panel nor squeezes its name.
        let name = ui.label("Device to connect");
        egui::ComboBox::from_id_salt("dynaclay device kind")
            .width(ui.available_width())
            .truncate()
            .selected_text(entry(self.kind))
            .show_ui(ui, |ui| {
                for i in 0..SPEC_KINDS.len() {
                    ui.selectable_value(&mut self.kind, i, entry(i));
                }
            })
            .response
            .labelled_by(name.id);
        let label = ui.label("Port / profile / file");
        ui.add(egui::TextEdit::singleline(&mut self.argument).desired_width(f32::INFINITY))
            .labelled_by(label.id);
        let spec = self.spec();
        match &spec {
            Ok(s) => ui.weak(format!("--device {s}")),
            Err(e) => ui.colored_label(ui.visuals().error_fg_color, e.to_string()),
        };
        let limit = ui.add(
            egui::Slider::new(&mut self.max_force_n, 0.0..=MAX_FORCE_LIMIT_N).text("Max force N"),
        );
        if limit.changed() && status.state == DeviceLinkState::Connected {
            action = Some(DeviceAction::SetMaxForce {
                max_force_n: self.max_force_n,
            });
        }
        if haptic_gain_slider(ui, &mut self.haptic_gain) {
            action = Some(DeviceAction::SetHapticGain {
                gain: self.haptic_gain,
            });
        }
        ui.horizontal_wrapped(|ui| {
            if ui
                .add_enabled(spec.is_ok(), egui::Button::new("Connect"))
                .clicked()
                && let Ok(spec) = &spec
            {
                action = Some(DeviceAction::Connect {
                    spec: spec.clone(),
                    max_force_n: self.max_force_n,
                });
            }
            if ui
                .add_enabled(
                    status.state != DeviceLinkState::Disconnected,
                    egui::Button::new("Disconnect"),
                )
                .clicked()
            {
                action = Some(DeviceAction::Disconnect);
            }
            // Enumeration reads sysfs and /proc and loads the vendor libraries: only on
            // request, never per frame.
            if ui.button("Scan").clicked() {
                let (mut found, notes) = enumerate::list_all();
                enumerate::diagnose_libraries(&mut found, &enumerate::vendor_libraries());
                self.scanned = Some((found, notes));
            }
        });
        if let Some((found, notes)) = &self.scanned {
            let mut pick = None;
            if found.is_empty() {
                ui.weak("nothing found");
            }
            for d in found {
                let name = d.product.as_deref().unwrap_or("unknown");
                let mut text = format!("{} {} {}", d.path, name, access_note(d.access));
                for p in &d.problems {
                    if *p != enumerate::Problem::PermissionDenied {
                        text.push_str(&format!(" (cannot open: {p})"));
                    }
                }
                match &d.spec {
                    Some(spec) => {
                        if ui.link(format!("{text}: use {spec}")).clicked() {
                            pick = Some(spec.clone());
                        }
                    }
                    None => {
                        ui.weak(text);
                    }
                }
            }
            for n in notes {
                ui.weak(n);
            }
            if let Some(s) = pick {
                self.set_spec_text(&s);
            }
        }
        action
    }
}

/// The index in [`SPEC_KINDS`] of a spec text's kind (its first word).
fn kind_index(text: &str) -> Option<usize> {
    let kind = text.split_once(':').map_or(text, |(k, _)| k);
    SPEC_KINDS.iter().position(|k| k.0 == kind)
}

fn access_note(a: Access) -> &'static str {
    match a {
        Access::Ok => "",
        Access::Denied => "(no permission: see the udev rules)",
        Access::Missing => "(gone)",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spec_text_round_trips_through_the_devices_parser() {
        let mut p = DevicePanel::default();
        assert_eq!(p.spec(), Ok(DeviceSpec::Sim));
        p.set_spec_text("serial:/dev/ttyUSB0:cartesian-serial");
        assert_eq!(p.spec_text(), "serial:/dev/ttyUSB0:cartesian-serial");
        assert!(matches!(p.spec(), Ok(DeviceSpec::Serial { .. })));
        p.set_spec_text("falcon");
        let err = p.spec().unwrap_err();
        assert!(err.to_string().contains("falcon"), "{err}");
        p.set_spec_text("nonsense:x");
        assert_eq!(
            p.spec_text(),
            "falcon",
            "unknown kinds leave the panel unchanged"
        );
    }

    #[test]
    fn the_list_follows_the_engines_device_once_per_switch() {
        let mut p = DevicePanel::default();
        let mut status = DeviceStatus {
            state: DeviceLinkState::Connected,
            spec: Some(DeviceSpec::Pointer),
            ..DeviceStatus::default()
        };
        p.follow(&status);
        assert_eq!(
            p.spec(),
            Ok(DeviceSpec::Pointer),
            "starts on the device in use"
        );
        p.set_spec_text("serial:/dev/ttyUSB0");
        p.follow(&status);
        assert_eq!(
            p.spec_text(),
            "serial:/dev/ttyUSB0",
            "the user's choice stays"
        );
        status.spec = Some(DeviceSpec::Sim);
        p.follow(&status);
        assert_eq!(p.spec(), Ok(DeviceSpec::Sim), "a switch is taken in");
    }
}
