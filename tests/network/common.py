"""What the network tests share: a box on the sim board with its web page (and MQTT), a broker,
and waiting with a deadline. The password's hash is made here with Python's own PBKDF2, not by
the box."""
import hashlib
import http.client
import json
import os
import re
import socket
import ssl
import subprocess
import sys
import time
import urllib.error
import urllib.request

PASSWORD = "correct horse"
# A test run with --tls: the page over https (--web-tls, a certificate from a test authority
# made here), its plain port only redirecting; every request and connection below goes over TLS.
TLS = "--tls" in sys.argv[1:]
_trusted = {"context": None}


def sh_in(work, *args):
    subprocess.run(args, check=True, cwd=work, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)


def test_authority(work, name):
    """A test CA (ca.crt) and a certificate it signed for 127.0.0.1 (NAME.crt, NAME.key) in WORK,
    made with openssl; their paths."""
    if not os.path.exists(os.path.join(work, "ca.crt")):
        sh_in(work, "openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2",
              "-subj", "/CN=calbox test CA", "-keyout", "ca.key", "-out", "ca.crt")
    sh_in(work, "openssl", "req", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=127.0.0.1",
          "-keyout", name + ".key", "-out", name + ".csr")
    with open(os.path.join(work, "san.ext"), "w") as f:
        f.write("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    sh_in(work, "openssl", "x509", "-req", "-in", name + ".csr", "-CA", "ca.crt", "-CAkey",
          "ca.key", "-CAcreateserial", "-days", "2", "-extfile", "san.ext", "-out", name + ".crt")
    return tuple(os.path.join(work, f) for f in ("ca.crt", name + ".crt", name + ".key"))


def trust(ca_file):
    """Requests and connections over TLS check the page's certificate against CA_FILE."""
    _trusted["context"] = ssl.create_default_context(cafile=ca_file)


def connect(port, source="127.0.0.1", timeout=10, handshake=True):
    """A connection to the page's port from SOURCE: over TLS (its handshake done) when TLS."""
    s = socket.create_connection(("127.0.0.1", port), timeout=timeout,
                                 source_address=(source, 0))
    if TLS and handshake:
        s = _trusted["context"].wrap_socket(s, server_hostname="127.0.0.1")
    return s


def http_connection(port, source="127.0.0.1", timeout=15):
    if TLS:
        return http.client.HTTPSConnection("127.0.0.1", port, timeout=timeout,
                                           source_address=(source, 0),
                                           context=_trusted["context"])
    return http.client.HTTPConnection("127.0.0.1", port, timeout=timeout,
                                      source_address=(source, 0))


def password_hash(password, salt=bytes(range(16)), iterations=100000):
    digest = hashlib.pbkdf2_hmac("sha256", password.encode(), salt, iterations)
    return "pbkdf2-sha256:%d:%s:%s" % (iterations, salt.hex(), digest.hex())


def process_mib(pid, field):
    """A field of /proc/PID/status in MiB ("VmHWM", the peak; "VmRSS", now)."""
    for line in open("/proc/%d/status" % pid):
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no %s for process %d" % (field, pid))


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Run:
    def __init__(self, work):
        self.work = work
        self.children = []

    def fail(self, why):
        print("FAIL: " + why)
        err = os.path.join(self.work, "box.err")
        if os.path.exists(err):
            print("== box.err (last 40 lines)")
            print("".join(open(err, errors="replace").readlines()[-40:]))
        self.stop_all()
        sys.exit(1)

    def stop_all(self):
        for child in self.children:
            if child.poll() is None:
                child.kill()
                child.wait()

    def wait_for(self, what, predicate, seconds, box=None):
        give_up = time.monotonic() + seconds
        while time.monotonic() < give_up:
            value = predicate()
            if value:
                return value
            if box is not None and box.poll() is not None:
                self.fail("calbox exited %d while waiting for %s" % (box.returncode, what))
            time.sleep(0.1)
        self.fail("no %s within %d s" % (what, seconds))

    def broker(self):
        port = free_port()
        conf = os.path.join(self.work, "mosquitto.conf")
        with open(conf, "w") as f:
            f.write("listener %d 127.0.0.1\nallow_anonymous true\npersistence false\n" % port)
        broker = subprocess.Popen(["/usr/sbin/mosquitto", "-c", conf],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.children.append(broker)

        def listening():
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                return True
            except OSError:
                return False
        self.wait_for("the broker", listening, 10)
        return broker, port

    def box(self, calbox, top, data, extra, config_text,
            scenario="tests/scenarios/delta_cycle_small.toml"):
        """A box on the sim board serving its page; (its process, the page's URL). When TLS, the
        page is over https with a certificate from the test authority (trusted from here on),
        and self.plain_port is the plain port that redirects to it."""
        os.makedirs(data, exist_ok=True)
        web_tls = []
        if TLS:
            ca, cert, key = test_authority(self.work, "page")
            trust(ca)
            keys = 'tls_cert = "%s"\ntls_key = "%s"\n' % (cert, key)
            config_text = (config_text.replace("[web]\n", "[web]\n" + keys, 1)
                           if "[web]\n" in config_text else config_text + "\n[web]\n" + keys)
            web_tls = ["--web-tls", "127.0.0.1:0"]
        with open(os.path.join(data, "calbox.toml"), "w") as f:
            f.write(config_text)
        err = open(os.path.join(self.work, "box.err"), "w")
        box = subprocess.Popen(
            [calbox, "run", "--board", "sim", "--scenario",
             os.path.join(top, scenario), "--data", data,
             "--web", "127.0.0.1:0", "--console", ""] + web_tls + extra,
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err)
        self.children.append(box)
        scheme = "https" if TLS else "http"

        def page_port():
            text = open(os.path.join(self.work, "box.err"), errors="replace").read()
            m = re.search(r"web: the page at %s://127\.0\.0\.1:(\d+)/" % scheme, text)
            plain = re.search(r"web: http://127\.0\.0\.1:(\d+)/ only sends", text)
            if TLS and plain:
                self.plain_port = int(plain.group(1))
            return int(m.group(1)) if m and (plain or not TLS) else None
        port = self.wait_for("the page's port in the log", page_port, 20, box)
        return box, "%s://127.0.0.1:%d" % (scheme, port)

    def log(self):
        return open(os.path.join(self.work, "box.err"), errors="replace").read()


def request(url, method="GET", body=None, headers=None, password=None, timeout=15):
    """(status, headers, body bytes) of one request; a refusal is an answer, not an error."""
    headers = dict(headers or {})
    data = None
    if body is not None:
        data = body if isinstance(body, bytes) else json.dumps(body).encode()
        headers.setdefault("Content-Type", "application/json")
    if password is not None:
        import base64
        headers["Authorization"] = "Basic " + base64.b64encode(
            ("calbox:" + password).encode()).decode()
    req = urllib.request.Request(url, data=data, method=method, headers=headers)
    context = _trusted["context"] if url.startswith("https:") else None
    try:
        with urllib.request.urlopen(req, timeout=timeout, context=context) as r:
            return r.status, r.headers, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers, e.read()


def get_json(url):
    status, _, body = request(url)
    if status != 200:
        raise RuntimeError("%s: %d %s" % (url, status, body[:200]))
    return json.loads(body)


def headless_chromium(work, height_px):
    """Debian's Chromium under its chromedriver, headless, 1280 px wide, its profile in `work`."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--disable-background-networking", "--window-size=1280,%d" % height_px,
              "--user-data-dir=" + os.path.join(work, "chromium")):
        options.add_argument(a)
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
