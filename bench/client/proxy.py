#!/usr/bin/env python3
"""The client benchmark's delaying proxy and page server, Python 3 standard library only.

    python3 proxy.py --port P --upstream http://127.0.0.1:S [--delay-ms 30] [--static DIR]

The same behaviour as proxy.mjs, for a machine without Node.js (run.sh: PROXY=python, chosen
automatically when node is missing):
* Every request under /tiles/ and /layers is held DELAY ms, then forwarded to the upstream
  tinstream-server over a keep-alive connection (one per proxy thread; a thread per client
  connection, so as many requests in flight as the client sends); the answer goes back with its
  status, headers and (compressed) body unchanged, except that a chunked body is sent with a
  Content-Length.
* It counts what it forwards: requests, answers by status, response bytes (status line, headers
  and body as received from upstream), body bytes, the most requests in flight at once, and
  requests and bytes by kind. GET /__stats returns the counters as JSON (proxy.mjs's fields);
  GET /__reset zeroes them (before each measured run).
* With --static DIR it serves DIR's files for every other path.
Prints "listening PORT" on stdout once ready.
"""
import argparse
import http.client
import http.server
import json
import mimetypes
import os
import sys
import threading
import time
import urllib.parse

HOP = {'connection', 'keep-alive', 'transfer-encoding', 'proxy-connection', 'te', 'trailer',
       'upgrade'}


def zero():
    return {'requests': 0, 'status': {}, 'bytes': 0, 'body_bytes': 0, 'in_flight': 0,
            'max_in_flight': 0, 'by_kind': {}}


def kind_of(path):
    if path.startswith('/layers'):
        return 'layers'
    if path.endswith('/layer.json'):
        return 'layer.json'
    if path.endswith('.terrain'):
        return 'terrain'
    return 'native'


class State:
    def __init__(self, upstream, delay_s, static_dir):
        self.upstream = upstream
        self.delay_s = delay_s
        self.static_dir = static_dir
        self.lock = threading.Lock()
        self.stats = zero()
        self.local = threading.local()

    def connection(self, fresh=False):
        conn = getattr(self.local, 'conn', None)
        if conn is None or fresh:
            if conn is not None:
                conn.close()
            conn = http.client.HTTPConnection(self.upstream.hostname, self.upstream.port or 80,
                                              timeout=600)
            self.local.conn = conn
        return conn


class Handler(http.server.BaseHTTPRequestHandler):
    protocol_version = 'HTTP/1.1'  # keep-alive towards the client
    state = None  # set in main

    def log_message(self, fmt, *args):  # quiet, like proxy.mjs
        pass

    def reply(self, status, body, content_type):
        self.send_response(status)
        self.send_header('Content-Type', content_type)
        self.send_header('Content-Length', str(len(body)))
        self.end_headers()
        if self.command != 'HEAD':
            self.wfile.write(body)

    def do_GET(self):
        path = self.path.split('?')[0]
        st = self.state
        if path == '/__stats':
            with st.lock:
                body = json.dumps(st.stats).encode()
            self.reply(200, body, 'application/json')
        elif path == '/__reset':
            with st.lock:
                st.stats = zero()
            self.reply(200, b'{}', 'application/json')
        elif path.startswith('/tiles/') or path.startswith('/layers'):
            self.forward(path)
        else:
            self.serve_static(path)

    do_HEAD = do_GET

    def forward(self, path):
        st = self.state
        kind = kind_of(path)
        with st.lock:
            counted = st.stats  # a reset during the request starts a new set of counters
            counted['requests'] += 1
            counted['in_flight'] += 1
            counted['max_in_flight'] = max(counted['max_in_flight'], counted['in_flight'])
            k = counted['by_kind'].setdefault(kind, {'requests': 0, 'bytes': 0})
            k['requests'] += 1
        time.sleep(st.delay_s)
        length = int(self.headers.get('Content-Length') or 0)
        request_body = self.rfile.read(length) if length else None
        headers = {name: value for name, value in self.headers.items()
                   if name.lower() not in HOP and name.lower() != 'host'}
        headers['Host'] = st.upstream.netloc
        headers['Connection'] = 'keep-alive'
        try:
            for attempt in (0, 1):  # a keep-alive connection the server closed: once more
                try:
                    conn = st.connection(fresh=attempt == 1)
                    conn.request(self.command, self.path, body=request_body, headers=headers)
                    up = conn.getresponse()
                    body = up.read()
                    break
                except (http.client.RemoteDisconnected, ConnectionResetError,
                        BrokenPipeError, http.client.CannotSendRequest):
                    if attempt == 1:
                        raise
            head = f'HTTP/1.1 {up.status} {up.reason}\r\n' + ''.join(
                f'{name}: {value}\r\n' for name, value in up.getheaders())
            head_bytes = len(head.encode('latin-1')) + 2
            with st.lock:
                counted['bytes'] += head_bytes + len(body)
                counted['body_bytes'] += len(body)
                k['bytes'] += head_bytes + len(body)
                key = str(up.status)
                counted['status'][key] = counted['status'].get(key, 0) + 1
                counted['in_flight'] -= 1
            self.send_response_only(up.status, up.reason)
            for name, value in up.getheaders():
                if name.lower() not in HOP and name.lower() != 'content-length':
                    self.send_header(name, value)
            if up.status not in (204, 304) and not 100 <= up.status < 200:
                self.send_header('Content-Length', str(len(body)))
            self.end_headers()
            if self.command != 'HEAD':
                self.wfile.write(body)
        except OSError as e:
            with st.lock:
                counted['in_flight'] -= 1
                counted['status']['error'] = counted['status'].get('error', 0) + 1
            st.connection(fresh=True)
            self.reply(502, f'proxy: {e}\n'.encode(), 'text/plain')

    def serve_static(self, path):
        root = self.state.static_dir
        rel = os.path.normpath(urllib.parse.unquote(path)).lstrip('/\\')
        file = os.path.join(root, rel or 'index.html') if root else ''
        if not root or not os.path.abspath(file).startswith(root) or not os.path.isfile(file):
            self.reply(404, b'', 'text/plain')
            return
        with open(file, 'rb') as f:
            body = f.read()
        self.send_response(200)
        self.send_header('Content-Type',
                         mimetypes.guess_type(file)[0] or 'application/octet-stream')
        self.send_header('Content-Length', str(len(body)))
        self.send_header('Cache-Control', 'no-store')
        self.end_headers()
        if self.command != 'HEAD':
            self.wfile.write(body)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--port', type=int, default=0)
    ap.add_argument('--upstream', default='http://127.0.0.1:8080')
    ap.add_argument('--delay-ms', type=float, default=30)
    ap.add_argument('--static', default='')
    a = ap.parse_args()
    Handler.state = State(urllib.parse.urlsplit(a.upstream), a.delay_ms / 1000.0,
                          os.path.abspath(a.static) if a.static else '')
    server = http.server.ThreadingHTTPServer(('127.0.0.1', a.port), Handler)
    server.daemon_threads = True
    print(f'listening {server.server_address[1]}', flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == '__main__':
    sys.exit(main())
