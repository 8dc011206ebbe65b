#!/usr/bin/python3
"""A PLC drives the box over Modbus TCP, as PLCs drive smart cameras: pymodbus (an independent
peer) sets the trigger coil, reads busy, confirms the review, reads done, the counter and the
result block; the box, meanwhile a Modbus client itself, writes the same result into a pymodbus
server standing for the machine's controller. Exception responses and a peer that stalls
mid-frame are checked on the way. Usage: plc_cycle.py CALBOX SOURCE_DIR"""
import logging
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

from pymodbus.client import ModbusTcpClient

calbox, top = sys.argv[1], sys.argv[2]
logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
work = tempfile.mkdtemp(prefix="calbox-plc-")
children = []


def fail(why):
    print("FAIL: " + why)
    for name in ("box.err",):
        path = os.path.join(work, name)
        if os.path.exists(path):
            print("== " + name)
            print("".join(open(path).readlines()[-30:]))
    for child in children:
        child.kill()
    sys.exit(1)


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def wait_for(what, predicate, seconds):
    give_up = time.monotonic() + seconds
    while time.monotonic() < give_up:
        value = predicate()
        if value:
            return value
        if children[-1].poll() is not None:
            fail("calbox exited %d while waiting for %s" % (children[-1].returncode, what))
        time.sleep(0.2)
    fail("no %s within %d s" % (what, seconds))


def floats_abcd(words):
    return [struct.unpack(">f", struct.pack(">HH", words[i], words[i + 1]))[0]
            for i in range(0, len(words), 2)]


# Coils, discrete inputs and registers as the README's map gives them.
TRIGGER, CONFIRM = 0, 1
READY, BUSY, REVIEW, DONE, PASS, ERROR = 0, 1, 2, 3, 4, 5
STATE, ERROR_CODE, COUNTER, WORD_ORDER, BLOCK = 0, 1, 2, 3, 4
NAMES = ["measured_xy_rms_mm", "measured_xy_max_mm", "predicted_xy_rms_mm",
         "predicted_xy_max_mm", "verified_xy_rms_mm", "verified_xy_max_mm", "diagonal_rod_mm",
         "diagonal_rod_trim_a_mm", "diagonal_rod_trim_b_mm", "diagonal_rod_trim_c_mm",
         "radius_mm", "tower_angle_trim_a_deg", "tower_angle_trim_b_deg",
         "tower_angle_trim_c_deg", "endstop_offset_a_mm", "endstop_offset_b_mm",
         "endstop_offset_c_mm", "height_mm"]

plc_port, controller_port = free_port(), free_port()
controller = subprocess.Popen(["/usr/bin/python3", os.path.join(top, "tests/modbus/pymodbus_server.py"),
                               "tcp", str(controller_port)], stdout=subprocess.DEVNULL)
children.append(controller)
# The configuration switches the client on and names a server the command line overrides.
config = os.path.join(work, "calbox.toml")
with open(config, "w") as f:
    f.write('[modbus]\nserver = "tcp:127.0.0.1:1"\nclient = "tcp:127.0.0.1:%d"\n'
            'word_order = "abcd"\nresponse_timeout_ms = 2000\n' % controller_port)
box = subprocess.Popen([calbox, "run", "--board", "sim", "--operator", "--config", config,
                        "--scenario", os.path.join(top, "tests/scenarios/delta_cycle_small.toml"),
                        "--data", os.path.join(work, "box"),
                        "--modbus-server", "tcp:127.0.0.1:%d" % plc_port],
                       stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                       stderr=open(os.path.join(work, "box.err"), "w"))
children.append(box)

plc = ModbusTcpClient("127.0.0.1", port=plc_port, timeout=3)
wait_for("the box's Modbus server", lambda: plc.connect(), 30)


def inputs():
    r = plc.read_discrete_inputs(0, 7, slave=1)
    if r.isError():
        fail("reading the discrete inputs: %s" % r)
    return r.bits[:7]


def registers(first, count):
    r = plc.read_input_registers(first, count, slave=1)
    if r.isError():
        fail("reading input registers %d+%d: %s" % (first, count, r))
    return r.registers


bits = inputs()
if not bits[READY] or bits[BUSY] or bits[DONE]:
    fail("at start: ready, busy, done = %s" % bits[:4])
if registers(0, 4) != [0, 0, 0, 0]:
    fail("at start: state, error code, counter, word order = %s" % registers(0, 4))

# Exception responses: an address beyond the map (2), a value a coil cannot take (3).
r = plc.read_coils(100, 1, slave=1)
if not r.isError() or r.exception_code != 2:
    fail("reading coil 100: expected exception 2, got %s" % r)
r = plc.read_input_registers(30, 20, slave=1)
if not r.isError() or r.exception_code != 2:
    fail("reading input registers 30+20: expected exception 2, got %s" % r)
r = plc.write_register(0, 5, slave=1)
if not r.isError() or r.exception_code != 2:
    fail("writing holding register 0 (the map has none): expected exception 2, got %s" % r)
raw = socket.create_connection(("127.0.0.1", plc_port))
raw.sendall(struct.pack(">HHHBBHH", 7, 0, 6, 1, 0x05, TRIGGER, 0x1234))  # not 0xFF00 or 0
answer = raw.recv(64)
if answer[7:9] != bytes([0x85, 0x03]):
    fail("a coil written 0x1234: expected exception 0x85 03, got %s" % answer.hex())
raw.close()

# A peer that sends half a frame and stalls is dropped; the PLC is still answered meanwhile.
stalled = socket.create_connection(("127.0.0.1", plc_port))
stalled.sendall(bytes([0, 9, 0, 0]))
started = time.monotonic()
inputs()
stalled.settimeout(5)
if stalled.recv(16) != b"":
    fail("the stalled peer got an answer instead of being dropped")
if time.monotonic() - started > 4:
    fail("the stalled peer held the server %.1f s" % (time.monotonic() - started))
stalled.close()

# The cycle: trigger, busy, review, confirm, done.
if plc.write_coil(TRIGGER, True, slave=1).isError():
    fail("writing the trigger coil")
wait_for("busy", lambda: inputs()[BUSY], 10)
if plc.read_coils(TRIGGER, 1, slave=1).bits[0]:
    fail("the trigger coil was not cleared by the box")
wait_for("review", lambda: inputs()[REVIEW], 900)
if registers(STATE, 1)[0] != 8:
    fail("in review the state register reads %d, not 8" % registers(STATE, 1)[0])
if plc.write_coil(CONFIRM, True, slave=1).isError():
    fail("writing the confirm coil")
wait_for("done", lambda: inputs()[DONE], 900)
bits = inputs()
if not bits[PASS] or bits[ERROR] or bits[BUSY] or not bits[READY]:
    fail("after the cycle: ready, busy, review, done, pass, error = %s" % bits[:6])
head = registers(0, 4)
if head != [0, 0, 1, 0]:
    fail("after the cycle: state, error code, counter, word order = %s" % head)
block_words = registers(BLOCK, 36)
values = dict(zip(NAMES, floats_abcd(block_words)))
checks = [("measured_xy_rms_mm", 0.05, 1.0), ("verified_xy_rms_mm", 0.0, 0.004),
          ("verified_xy_max_mm", 0.0, 0.008), ("predicted_xy_rms_mm", 0.0, 0.01),
          ("diagonal_rod_mm", 249.0, 253.0), ("radius_mm", 139.0, 142.0),
          ("height_mm", 299.0, 302.0)]
for name, low, high in checks:
    if not low <= values[name] <= high:
        fail("%s = %.5f, expected %g to %g" % (name, values[name], low, high))

# The box wrote the same block to the controller's holding registers 0..35.
controller_client = ModbusTcpClient("127.0.0.1", port=controller_port, timeout=3)
controller_client.connect()
written = wait_for("the result at the controller", lambda: (
    lambda r: None if r.isError() or not any(r.registers) else r.registers)(
        controller_client.read_holding_registers(0, 36, slave=1)), 10)
if written != block_words:
    fail("the controller holds %s, the result block is %s" % (written, block_words))

box.send_signal(signal.SIGTERM)
box.wait(timeout=20)
controller.kill()
print("plc: trigger -> busy -> review -> confirm -> done; counter 1; before %.4f mm, verified "
      "%.4f (%.4f) mm; the controller holds the same 36 registers" % (
          values["measured_xy_rms_mm"], values["verified_xy_rms_mm"],
          values["verified_xy_max_mm"]))
