#!/usr/bin/env bash
# The window in a real (virtual) display: starts `dynaclay gui` under Xvfb with the mouse as
# the tool, saves the session through the file dialog's typed-path fallback (Ctrl+Shift+S),
# drags a stroke across the clay with xdotool, saves again under another name (up to five
# times, until the stroke has reached the saved clay), and checks that the sessions were
# written and read back (`dynaclay render`), and that their renders differ (the stroke
# changed the clay).
#
# Needs Xvfb, xvfb-run and xdotool (`apt-get install xvfb xdotool`), a Vulkan driver for wgpu
# (lavapipe: `apt-get install mesa-vulkan-drivers`) and a built binary
# (`cargo build --release`; `DYNACLAY_BIN` names another). Exit status 0 when every check
# passed; the window's output is in the scratch folder it prints on failure.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${DYNACLAY_BIN:-${CARGO_TARGET_DIR:-$root/target}/release/dynaclay}
[ -x "$bin" ] || { echo "gui_smoke: no binary at $bin (cargo build --release)"; exit 2; }
for tool in xvfb-run xdotool; do
    command -v "$tool" >/dev/null || { echo "gui_smoke: $tool is not installed"; exit 2; }
done
work=$(mktemp -d)
export DYNACLAY_BIN="$bin" GUI_SMOKE_WORK="$work"
# No desktop portal in a virtual display: the typed path is what is driven.
export DYNACLAY_FILE_DIALOG=typed
# The window's settings (recent files) go to the scratch folder, not the user's.
export XDG_CONFIG_HOME="$work/config"

xvfb-run -a -s "-screen 0 1400x900x24" bash -euo pipefail -c '
cd "$GUI_SMOKE_WORK"
"$DYNACLAY_BIN" gui --device mouse >gui.log 2>&1 &
gui=$!
trap "kill $gui 2>/dev/null || true" EXIT
# The window, once mapped (the engine starts and the platform probe runs first).
win=""
for _ in $(seq 1 120); do
    win=$(xdotool search --onlyvisible --name "^dynaclay$" 2>/dev/null | head -n 1 || true)
    [ -n "$win" ] && break
    kill -0 $gui 2>/dev/null || { echo "gui_smoke: the window exited"; cat gui.log; exit 1; }
    sleep 0.5
done
[ -n "$win" ] || { echo "gui_smoke: no window"; cat gui.log; exit 1; }
xdotool windowactivate --sync "$win" 2>/dev/null || xdotool windowfocus --sync "$win"
eval "$(xdotool getwindowgeometry --shell "$win")"
sleep 3

save_as() {
    xdotool key --window "$win" ctrl+shift+s
    sleep 1
    # The path field opens holding the current name, focused: replace all of it.
    xdotool key --window "$win" ctrl+a
    xdotool type --delay 20 "$GUI_SMOKE_WORK/$1"
    xdotool key Return
    for _ in $(seq 1 60); do
        [ -s "$GUI_SMOKE_WORK/$1" ] && return 0
        sleep 0.5
    done
    echo "gui_smoke: $1 was not written"; cat gui.log; exit 1
}

save_as before.dclay
# A stroke: left drag across the middle of the view (between the side panels), where the
# clay is framed.
cx=$((X + WIDTH / 2)); cy=$((Y + HEIGHT / 2))
xdotool mousemove --sync $((cx - 60)) "$cy"
sleep 0.5
xdotool mousedown 1
for step in $(seq 0 4 120); do
    xdotool mousemove $((cx - 60 + step)) $((cy + step / 4))
    sleep 0.03
done
sleep 1
xdotool mouseup 1
# The stroke reaches the clay through the loops: save until the saved clay shows it (a
# loaded machine settles later), at most five times.
"$DYNACLAY_BIN" render before.dclay --out before.png >render-before.log 2>&1 \
    || { echo "gui_smoke: FAIL: before.dclay does not render"; cat render-before.log; exit 1; }
for n in 1 2 3 4 5; do
    sleep 2
    save_as "after$n.dclay"
    "$DYNACLAY_BIN" render "after$n.dclay" --out "after$n.png" >"render-after$n.log" 2>&1 \
        || { echo "gui_smoke: FAIL: after$n.dclay does not render"; cat "render-after$n.log"; exit 1; }
    # The saved files differ by their save time anyway: the clays are compared through their
    # renders (the same clay renders to the same image).
    if ! cmp -s before.png "after$n.png"; then
        echo "gui_smoke: ok: before.dclay and after$n.dclay written through the typed path; \
their renders differ (the stroke changed the clay)"
        exit 0
    fi
done
echo "gui_smoke: FAIL: the stroke did not change the saved clay (five saves)"
exit 1
' && status=0 || status=$?
if [ "$status" = 0 ]; then
    rm -rf "$work"
else
    echo "gui_smoke: scratch left in $work"
fi
exit $status
