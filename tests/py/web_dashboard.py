"""Drives ecatd's dashboard in headless Chromium (WebDriver) and reports what it saw.

Called by tests/tests/server/web_dashboard.rs with one JSON argument (ecatd's addresses, the
tokens, the `ecat` binary, the FoE file, the screenshot folder). It acts as a user would
(keyboard and clicks), waits for each result with a deadline, and prints one JSON object of
observations; the Rust test decides whether they are right. One browser session for all.
"""

import json
import socket
import subprocess
import sys
import time
import urllib.request

from selenium import webdriver
from selenium.common.exceptions import WebDriverException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.common.keys import Keys
from selenium.webdriver.support.select import Select

ARGS = json.loads(sys.argv[1])
BASE = ARGS["http"]
SHOTS = ARGS["screenshots"]
DEADLINE_S = 60
OUT = {"steps": []}


def browser():
    options = webdriver.ChromeOptions()
    options.binary_location = ARGS.get("chromium", "/usr/bin/chromium")
    for arg in [
        "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
        "--window-size=1280,800", "--no-first-run", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--disable-default-apps",
        "--disable-extensions", "--disable-domain-reliability", "--no-pings",
        "--metrics-recording-only", "--safebrowsing-disable-auto-update",
    ]:
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    service = Service(ARGS.get("chromedriver", "/usr/bin/chromedriver"))
    return webdriver.Chrome(service=service, options=options)


def viewport(d, width, height):
    # The page's own size (the window's includes the browser's frame).
    d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                      {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})


def wait(what, check, timeout=DEADLINE_S, record=True):
    """Polls `check()` until it returns something truthy; None after the deadline (a step
    that timed out, unless `record` is false)."""
    end = time.monotonic() + timeout
    while True:
        try:
            value = check()
        except WebDriverException:
            value = None
        if value:
            return value
        if time.monotonic() > end:
            if record:
                OUT["steps"].append(f"timed out waiting for {what}")
            return None
        time.sleep(0.1)


def on_events_view(d):
    """Whether the events view is shown (its hash and its table)."""
    return js(d, "return location.hash") == "#/events" and bool(d.find_elements(By.ID, "events"))


def open_and_wait(d, fragment, what, check):
    """Opens `fragment` and waits for `check`. Chromium drops the requests in flight when it
    sees a network interface come or go (`net::ERR_NETWORK_CHANGED`), and the tests that run
    beside this one make and remove namespaces, veth pairs and TAPs: a page whose reads were
    dropped so is opened once more, and counted in `network_changed`."""
    go(d, fragment)
    value = wait(what, check, timeout=20, record=False)
    if value:
        return value
    entries = d.get_log("browser")
    OUT.setdefault("console", []).extend({"phase": "reopen", **e} for e in entries)
    if any("ERR_NETWORK_CHANGED" in e.get("message", "") for e in entries):
        OUT["network_changed"] = OUT.get("network_changed", 0) + 1
        go(d, "#/events")
        wait("another view", lambda: on_events_view(d))
        go(d, fragment)
    return wait(what, check)


def js(d, script, *args):
    return d.execute_script(script, *args)


def shot(d, name, top=True):
    if top:
        js(d, "window.scrollTo(0, 0)")
    path = f"{SHOTS}/{name}.png"
    d.save_screenshot(path)
    OUT.setdefault("screenshots", []).append(path)


def logs(d, phase):
    """Console entries since the last call, tagged with the phase they belong to."""
    for entry in d.get_log("browser"):
        OUT.setdefault("console", []).append({"phase": phase, **entry})
    for entry in d.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        if message["method"] == "Network.requestWillBeSent":
            OUT.setdefault("requests", []).append(message["params"]["request"]["url"])


def go(d, fragment):
    js(d, "location.hash = arguments[0]", fragment)


def token_dialog(d, secret):
    wait("the token dialog", lambda: js(d, "return document.getElementById('token-dialog').open"))
    field = d.find_element(By.ID, "token-input")
    field.clear()
    field.send_keys(secret)
    field.send_keys(Keys.ENTER)  # the dialog form's first button: "Use token"
    wait("the dialog to close", lambda: not js(d, "return document.getElementById('token-dialog').open"))


def slaves_shown(d):
    return js(d, """return [...document.querySelectorAll('li.slave')].map(li => ({
        position: Number(li.dataset.position), state: li.dataset.state,
        name: li.querySelector('.slave-title a').textContent}))""")


def ecat(*args):
    run = subprocess.run([ARGS["ecat"], "--address", "http://" + ARGS["grpc"], "--token", ARGS["write_token"], *args],
                         capture_output=True, text=True, timeout=60)
    return {"status": run.returncode, "stderr": run.stderr}


def raise_emergency(position, code, register, data):
    """The simulator's debug route (`--simulate` only): the slave sends a CoE emergency."""
    body = json.dumps({"error_code": code, "error_register": register, "data": data}).encode()
    request = urllib.request.Request(f"{BASE}/api/v1/slaves/{position}/sim/emergency", data=body, method="POST",
                                     headers={"Content-Type": "application/json", "Authorization": "Bearer " + ARGS["write_token"]})
    with urllib.request.urlopen(request, timeout=30) as response:
        return response.status


def confirm(d, timeout=DEADLINE_S):
    """Presses Confirm in the write confirmation; the dialog's text."""
    wait("the confirmation", lambda: js(d, "const c = document.getElementById('confirm-dialog'); return c && c.open"), timeout)
    text = d.find_element(By.ID, "confirm-dialog").text
    d.find_element(By.ID, "confirm-ok").click()
    wait("the confirmation to close", lambda: not d.find_elements(By.ID, "confirm-dialog"))
    return text


WRITE_CONTROLS = """return [...document.querySelectorAll('.write')]
    .flatMap(el => el.matches('button, input, select') ? [el] : [...el.querySelectorAll('button, input, select')])
    .map(el => ({disabled: el.disabled, title: el.title}))"""


def open_object(d, index):
    node = wait(f"object {index}", lambda: d.find_element(By.ID, f"object-{index}"))
    wait(f"object {index}'s description", lambda: "…" not in node.find_element(By.TAG_NAME, "summary").text)
    summary = node.find_element(By.TAG_NAME, "summary")
    summary.send_keys(Keys.ENTER)  # keyboard: <summary> opens on Enter
    return node


def read_entry(d, entry_id):
    button = wait(f"{entry_id}'s Read button", lambda: d.find_element(By.CSS_SELECTOR, f"#{entry_id} button.read"))
    button.click()
    output = d.find_element(By.CSS_SELECTOR, f"#{entry_id} output")
    return wait(f"{entry_id}'s value", lambda: output.text not in ("", "not read", "reading…") and output.text)


def main():
    d = browser()
    try:
        viewport(d, 1280, 800)
        # No token: ecatd refuses, the dashboard asks for one.
        d.get(BASE + "/")
        OUT["token_prompt"] = bool(wait("the token prompt", lambda: js(d, "return document.getElementById('token-dialog').open")))
        shot(d, "token")
        logs(d, "token")
        token_dialog(d, ARGS["write_token"])
        OUT["role_label"] = wait("the role label", lambda: "read and write" in d.find_element(By.ID, "role").text and d.find_element(By.ID, "role").text)

        # Segment: every slave with its state; then a state change from the CLI, live.
        OUT["slaves"] = wait("five slaves", lambda: len(slaves_shown(d)) == ARGS["slave_count"] and slaves_shown(d))
        wait("the ports", lambda: len(d.find_elements(By.CSS_SELECTOR, "li.port")) > 0)
        wait("the event stream", lambda: js(d, "return document.getElementById('live').dataset.status") == "live")
        shot(d, "segment")
        js(d, "window.__notReloaded = true")
        OUT["cli_safeop"] = ecat("states", "-p", "2", "SAFEOP")
        OUT["state_after_cli"] = wait("slave 2 in SAFEOP", lambda: js(d, "return document.querySelector('li.slave[data-position=\"2\"]').dataset.state") == "SAFEOP" and "SAFEOP")
        OUT["not_reloaded"] = js(d, "return window.__notReloaded === true")
        shot(d, "segment-safeop")
        OUT["cli_op"] = ecat("states", "-p", "2", "OP")
        wait("slave 2 back in OP", lambda: js(d, "return document.querySelector('li.slave[data-position=\"2\"]').dataset.state") == "OP")
        logs(d, "segment")

        # Keyboard only: Tab to the Events link and press Enter.
        # From the top of the page: the skip link, then the views' links.
        js(d, "document.activeElement.blur(); window.scrollTo(0, 0)")
        for _ in range(20):
            ActionChains(d).send_keys(Keys.TAB).perform()
            if js(d, "return document.activeElement.dataset.view") == "events":
                ActionChains(d).send_keys(Keys.ENTER).perform()
                break
        OUT["keyboard_view"] = wait("the events view", lambda: on_events_view(d) and "#/events")
        OUT["emergency_raised"] = raise_emergency(0, ARGS["emergency_code"], 0x11, "0102030405")
        wait("the emergency in the log", lambda: d.find_elements(By.CSS_SELECTOR, "#events tr.event-emergency"))
        Select(d.find_element(By.ID, "event-kind")).select_by_value("emergency")
        wait("ecatd's answer to the filter", lambda: js(d, "return document.querySelector('#events tbody').dataset.filtered") == "server")
        OUT["events_filtered"] = wait("the filtered log", lambda: (rows := [r.text for r in d.find_elements(By.CSS_SELECTOR, "#events tbody tr")]) and rows)
        shot(d, "events")

        # The CoE dictionary of slave 3: 0x1018:01 read, 0x2001:00 written.
        go(d, "#/slave/3")
        open_object(d, "1018")
        OUT["coe_1018_01"] = read_entry(d, "entry-1018-01")
        node = open_object(d, "2001")
        editor = wait("0x2001:00's editor", lambda: d.find_element(By.CSS_SELECTOR, "#entry-2001-00 .editor"))
        editor.clear()
        editor.send_keys(str(ARGS["coe_write_value"]))
        d.find_element(By.CSS_SELECTOR, "#entry-2001-00 button.write-value").click()
        # The confirmation names slave, object and value; nothing is written before it.
        OUT["coe_confirm"] = confirm(d)
        OUT["coe_write_status"] = wait("the write's result", lambda: (t := d.find_element(By.CSS_SELECTOR, "#entry-2001-00 .write-status").text) not in ("", "writing…") and t)
        OUT["coe_2001_00_shown"] = wait("0x2001:00 read back", lambda: d.find_element(By.CSS_SELECTOR, "#entry-2001-00 output").text == str(ARGS["coe_write_value"]) and str(ARGS["coe_write_value"]))
        js(d, "arguments[0].scrollIntoView()", d.find_element(By.ID, "object-1018"))
        shot(d, "slave-dictionary", top=False)
        logs(d, "coe")

        # FoE: 1 MiB written with the progress bar, then read back.
        # The page's own mailbox reads first (counters, dictionary, IDNs, IP settings): the
        # file transfer then has the slave's mailbox to itself.
        open_and_wait(d, "#/slave/0", "the slave page's reads", lambda: d.find_elements(By.ID, "eoe-ip") and d.find_elements(By.CSS_SELECTOR, "#view table"))
        name = wait("the FoE file name", lambda: d.find_element(By.ID, "foe-name"))
        name.clear()
        name.send_keys(ARGS["foe_name"])
        d.find_element(By.ID, "foe-file").send_keys(ARGS["foe_file"])
        d.find_element(By.ID, "foe-write").click()
        OUT["foe_confirm"] = confirm(d, timeout=120)
        status = d.find_element(By.ID, "foe-status")
        wait("the FoE write", lambda: status.text.startswith(("done", "failed")), timeout=120)
        OUT["foe_write"] = {
            "status": status.text,
            "progress": js(d, "return document.getElementById('foe-progress').value"),
            "sha256": status.get_attribute("data-sha256"),
        }
        js(d, "arguments[0].scrollIntoView()", d.find_element(By.ID, "foe-progress"))
        shot(d, "slave-foe", top=False)
        d.find_element(By.ID, "foe-read").click()
        wait("the FoE read", lambda: status.text.startswith(("read back", "failed")), timeout=120)
        OUT["foe_read"] = {
            "status": status.text,
            "progress": js(d, "return document.getElementById('foe-progress').value"),
            "sha256": status.get_attribute("data-sha256"),
            "size": status.get_attribute("data-size"),
        }
        OUT["slave_emergencies"] = d.find_element(By.ID, "emergencies").text
        shot(d, "slave")
        logs(d, "foe")

        # Gateway: the failure rate before and after malformed ETG.8200 requests.
        go(d, "#/gateway")
        rate = wait("the failure rate", lambda: d.find_element(By.ID, "failure-rate"))
        wait("two polls", lambda: js(d, "return document.querySelector('#chart-failure-rate path.line').dataset.last") != "")
        OUT["gateway_before"] = float(rate.get_attribute("data-overall"))
        host, port = ARGS["gateway"].rsplit(":", 1)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
            for i in range(ARGS["bad_requests"]):
                # Too short for an ETG.8200 request (spec-notes §gateway): counted as malformed.
                udp.sendto(bytes([0x42, i & 0xFF]), (host, int(port)))
        OUT["gateway_after"] = wait("the failure rate to rise", lambda: float(rate.get_attribute("data-overall")) > 5 and float(rate.get_attribute("data-overall")))
        OUT["gateway_chart_last"] = wait("the chart to show it", lambda: float(js(d, "return document.querySelector('#chart-failure-rate path.line').dataset.last") or 0) > 5
                                         and float(js(d, "return document.querySelector('#chart-failure-rate path.line').dataset.last")))
        OUT["gateway_malformed"] = d.find_element(By.ID, "failure-reasons").text
        wait("a few more samples", lambda: js(d, "return document.querySelectorAll('#chart-rps path.line')[0].getAttribute('d').split('L').length") >= 4)
        shot(d, "gateway")
        logs(d, "gateway")

        # Bus: the charts fill.
        go(d, "#/bus")
        OUT["bus_period"] = wait("the bus totals", lambda: "µs" in d.find_element(By.ID, "view").text and d.find_element(By.CSS_SELECTOR, "#view .facts dd").text)
        wait("a few samples", lambda: js(d, "return (document.querySelector('#chart-cycle path.line').getAttribute('d') || '').split('L').length") >= 4)
        shot(d, "bus")
        logs(d, "bus")

        # Dark theme and a tablet's width.
        go(d, "#/segment")
        button = d.find_element(By.ID, "theme-button")
        while "dark" not in button.text:
            button.send_keys(Keys.ENTER)
        OUT["dark_background"] = js(d, "return getComputedStyle(document.body).backgroundColor")
        wait("the segment", lambda: len(slaves_shown(d)) == ARGS["slave_count"])
        shot(d, "segment-dark")
        viewport(d, 768, 1024)
        js(d, "location.reload()")
        wait("the segment at tablet width", lambda: len(slaves_shown(d)) == ARGS["slave_count"])
        OUT["tablet_overflow"] = js(d, "return document.documentElement.scrollWidth > window.innerWidth")
        shot(d, "segment-tablet")
        viewport(d, 1280, 800)
        logs(d, "theme")

        # Read-only: the read token sees every write control disabled, and the badge.
        d.find_element(By.ID, "token-button").click()
        token_dialog(d, ARGS["read_token"])
        OUT["read_role_label"] = wait("the read-only label", lambda: "read only" in d.find_element(By.ID, "role").text and d.find_element(By.ID, "role").text)
        OUT["read_only_badge"] = d.find_element(By.ID, "read-only-badge").text if d.find_element(By.ID, "read-only-badge").is_displayed() else ""
        go(d, "#/segment")
        wait("the segment", lambda: len(slaves_shown(d)) == ARGS["slave_count"])
        OUT["read_only_segment_controls"] = js(d, WRITE_CONTROLS)
        go(d, "#/slave/3")
        open_object(d, "2001")
        OUT["read_only_value"] = read_entry(d, "entry-2001-00")
        wait("0x2001:00's editor", lambda: d.find_element(By.CSS_SELECTOR, "#entry-2001-00 .editor"))
        OUT["read_only_slave_controls"] = js(d, WRITE_CONTROLS)
        js(d, "arguments[0].scrollIntoView()", d.find_element(By.ID, "object-1018"))
        shot(d, "slave-read-only", top=False)
        go(d, "#/gateway")
        wait("the gateway", lambda: d.find_element(By.ID, "failure-rate").text != "–")
        wait("the gateway's control", lambda: d.find_elements(By.ID, "gateway-toggle"))
        OUT["read_only_gateway_controls"] = js(d, WRITE_CONTROLS)
        logs(d, "read-only")
    finally:
        d.quit()
    print(json.dumps(OUT))


main()
