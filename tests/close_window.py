# Closes every window named "coevo" as a window manager's close button does: a WM_DELETE_WINDOW client
# message, sent ARGV[1] seconds after the first such window appears. Used by tests/viewer.rs and by
# tests/stress/viewer-close.sh (Debian's python3-xlib).
import sys, time
from Xlib import display, protocol, X
after = float(sys.argv[1])
d = display.Display()
root = d.screen().root
def windows(w):
    for c in w.query_tree().children:
        yield c
        yield from windows(c)
def named():
    out = []
    for w in windows(root):
        try:
            name = w.get_wm_name()
        except Exception:
            continue
        if name and 'coevo' in str(name):
            out.append(w)
    return out
start = time.time()
while not named():
    if time.time() - start > 120:
        sys.exit("no coevo window")
    time.sleep(0.2)
time.sleep(after)
protocols, delete = d.intern_atom('WM_PROTOCOLS'), d.intern_atom('WM_DELETE_WINDOW')
targets = named()
if not targets:
    sys.exit("no coevo window to close at the moment of the close")
for w in targets:
    w.send_event(protocol.event.ClientMessage(window=w, client_type=protocols, data=(32, [delete, X.CurrentTime, 0, 0, 0])))
# A round trip before exiting (as Xlib's own XCloseDisplay makes): the server has then taken the request,
# and an error of it (a window gone meanwhile) is reported. With only a flush, the request was written
# but, beside a two-core load, Xvfb sometimes never delivered the close to the viewer (3 of 95 closes in
# tests/stress/viewer-close.sh; the viewer then answered a second close at once): a close lost on its way,
# which a test read as a viewer that ignores its window's close. With the round trip, 0 of 200.
d.sync()
print("sent WM_DELETE_WINDOW to", ", ".join(f"{w.id:#x} {w.get_wm_name()!r}" for w in targets))
