"""A screenshot of rerun's web viewer showing a recording, from headless
Chromium (how docs/rerun_web_viewer_kitti06.png was made).

    .deps/venv-viewer/bin/rerun --serve-web --web-viewer-port 9090 --port 9876 out/viewer_check/run.rrd &
    chromium --headless=new --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader \
        --window-size=1400,900 --remote-debugging-port=9222 --remote-allow-origins='*' \
        "http://127.0.0.1:9090/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A9876%2Fproxy" &
    python tools/rerun_web_screenshot.py OUT.png [SECONDS]   # needs `pip install websocket-client`

Waits SECONDS (default 45: the page loads the recording in real time;
`chromium --screenshot` with a virtual time budget shows an empty viewer)
and saves the page through the DevTools protocol.
"""

import base64
import json
import sys
import time
import urllib.request

import websocket


def main(out, seconds=45.0):
    tabs = json.load(urllib.request.urlopen("http://127.0.0.1:9222/json"))
    page = next(t for t in tabs if t["type"] == "page")
    ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=60)
    time.sleep(seconds)
    ws.send(json.dumps({"id": 1, "method": "Page.captureScreenshot", "params": {"format": "png"}}))
    while True:
        message = json.loads(ws.recv())
        if message.get("id") == 1:
            break
    with open(out, "wb") as f:
        f.write(base64.b64decode(message["result"]["data"]))
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else 45.0)
