//! Every key of the window and the action it names, in one table: the event loop looks keys up
//! here and the overlay's help prints it.

use winit::keyboard::KeyCode;

use crate::settings::Mode;

/// What a key does (pressed once; movement keys are held and read by the camera controller).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// 1–5: uniform, RIS, ReSTIR, path tracer, brute force.
    SetMode(Mode),
    /// G: indirect VPLs (global illumination) on/off.
    ToggleGi,
    /// L: a point light at the camera, a little in front of it.
    SpawnLight,
    /// Backspace: remove the last spawned light.
    RemoveLight,
    /// N / B: next / previous debug view; V: back to the final image.
    NextView,
    PreviousView,
    FinalView,
    /// Up / Down: twice / half the RIS candidates.
    MoreCandidates,
    FewerCandidates,
    /// P: progressive accumulation on/off.
    ToggleProgressive,
    /// Enter: write final.exr, final.png and summary.json to --out, as a headless run does.
    SaveImage,
    /// O / I: save the camera to camera.json / load it.
    SaveCamera,
    LoadCamera,
    /// Home: back to the scene's camera.
    HomeCamera,
    /// F1: overlay on/off.
    ToggleOverlay,
    /// F2: freeze the frame loop; F3: one frame while frozen.
    Freeze,
    Step,
    /// F4: render one frame with every pass's outputs written to --out/passes (as --dump-passes).
    DumpPasses,
    /// F12: render one frame inside a RenderDoc capture (when running under RenderDoc).
    RenderDocCapture,
    /// Esc: quit.
    Quit,
}

/// (key, label shown in help, action, what it does).
pub const KEYS: &[(KeyCode, &str, Action, &str)] = &[
    (KeyCode::Digit1, "1", Action::SetMode(Mode::Uniform), "uniform VPL sampling"),
    (KeyCode::Digit2, "2", Action::SetMode(Mode::Ris), "RIS over the VPLs"),
    (KeyCode::Digit3, "3", Action::SetMode(Mode::Restir), "ReSTIR DI over the VPLs"),
    (KeyCode::Digit4, "4", Action::SetMode(Mode::Pt), "path tracer (ground truth)"),
    (KeyCode::Digit5, "5", Action::SetMode(Mode::Bruteforce), "brute force over every VPL (small images)"),
    (KeyCode::KeyG, "G", Action::ToggleGi, "indirect VPLs (global illumination) on/off"),
    (KeyCode::KeyL, "L", Action::SpawnLight, "spawn a point light at the camera"),
    (KeyCode::Backspace, "Backspace", Action::RemoveLight, "remove the last spawned light"),
    (KeyCode::KeyN, "N", Action::NextView, "next debug view"),
    (KeyCode::KeyB, "B", Action::PreviousView, "previous debug view"),
    (KeyCode::KeyV, "V", Action::FinalView, "final image"),
    (KeyCode::ArrowUp, "Up", Action::MoreCandidates, "RIS candidates ×2"),
    (KeyCode::ArrowDown, "Down", Action::FewerCandidates, "RIS candidates ÷2"),
    (KeyCode::KeyP, "P", Action::ToggleProgressive, "progressive accumulation on/off"),
    (KeyCode::Enter, "Enter", Action::SaveImage, "write final.exr/png + summary.json to --out"),
    (KeyCode::KeyO, "O", Action::SaveCamera, "save the camera to camera.json"),
    (KeyCode::KeyI, "I", Action::LoadCamera, "load the camera from camera.json"),
    (KeyCode::Home, "Home", Action::HomeCamera, "back to the scene camera (--camera-path: play it again)"),
    (KeyCode::F1, "F1", Action::ToggleOverlay, "overlay on/off"),
    (KeyCode::F2, "F2", Action::Freeze, "freeze / resume the frame loop"),
    (KeyCode::F3, "F3", Action::Step, "one frame while frozen"),
    (KeyCode::F4, "F4", Action::DumpPasses, "dump the next frame's pass outputs to --out/passes"),
    (KeyCode::F12, "F12", Action::RenderDocCapture, "capture the next frame in RenderDoc (when run under it)"),
    (KeyCode::Escape, "Esc", Action::Quit, "quit"),
];

/// The held movement keys, for the help text.
pub const MOVE_KEYS: &[(&str, &str)] = &[
    ("W/A/S/D", "move forward / left / back / right"),
    ("Space / Left Ctrl", "move up / down"),
    ("Shift", "×6 speed"),
    ("right mouse button", "hold and drag to look around"),
    ("scroll wheel", "movement speed ×1.25 per notch"),
];

/// The action of a key, if it has one.
pub fn action_for(key: KeyCode) -> Option<Action> {
    KEYS.iter().find(|k| k.0 == key).map(|k| k.2)
}

/// The help text: one line per key.
pub fn help_rows() -> Vec<(&'static str, &'static str)> {
    KEYS.iter().map(|(_, label, _, what)| (*label, *what)).chain(MOVE_KEYS.iter().copied()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_key_is_bound_once() {
        for (i, a) in KEYS.iter().enumerate() {
            assert!(KEYS[i + 1..].iter().all(|b| b.0 != a.0), "{} is bound twice", a.1);
        }
        assert_eq!(action_for(KeyCode::Digit3), Some(Action::SetMode(Mode::Restir)));
        assert_eq!(action_for(KeyCode::KeyW), None, "movement keys belong to the controller");
    }
}
