"""`acl lsp` driven through Emacs's eglot, headless (issue 27, item 5): `emacs --batch` loads
editors/emacs/acl-mode.el, opens a copy of examples/fig2_vertical_cantilever.acl, connects with
the contact acl-mode.el adds to `eglot-server-programs', and asks through eglot what a user gets:
hover on a capsule, the imenu index (documentSymbol), `eglot-rename', `eglot-format-buffer', and
flymake's diagnostics after an error is typed into the buffer. Skips when Emacs or eglot (Emacs
29+, or ELPA/Debian's elpa-eglot on 26-28) is absent."""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pygls", reason="acl lsp needs the optional extra acl[lsp] (pygls)")

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "examples" / "fig2_vertical_cantilever.acl"
BAD = "param broken = 5 um * nosuch_name"

DRIVE = r"""
(require 'eglot)
(require 'flymake)
(require 'imenu)
(require 'json)
(setq eglot-sync-connect 20 eglot-connect-timeout 30 eglot-autoshutdown nil)
(defvar acl-out nil)
(defun acl-put (k v) (push (cons k v) acl-out))
(defun acl-wait (pred secs)
  "Accept process output until PRED holds or SECS pass; return PRED's value."
  (let ((end (+ (float-time) secs)) v)
    (while (and (not (setq v (funcall pred))) (< (float-time) end))
      (accept-process-output nil 0.05))
    v))
(defun acl-flymake ()
  (mapcar (lambda (d) (list (line-number-at-pos (flymake-diagnostic-beg d))
                            (format "%s" (flymake-diagnostic-text d))))
          (flymake-diagnostics)))
(defun acl-sync ()
  (eglot--signal-textDocument/didChange)
  (accept-process-output nil 0.1))
(defmacro acl-step (name &rest body)
  `(condition-case err (acl-put ,name (progn ,@body))
     (error (acl-put ,name (list :error (error-message-string err))))))
(unwind-protect
    (progn
      (find-file (getenv "ACL_EGLOT_DESIGN"))
      (acl-put "mode" (symbol-name major-mode))
      (let ((contact (eglot--guess-contact)))
        (acl-put "contact" (nth 3 contact))
        (acl-step "connect" (apply #'eglot contact) t))
      (acl-put "connected" (if (acl-wait #'eglot-current-server 30) t :false))
      ;; diagnostics of the untouched example (it carries one `acl: ignore')
      (flymake-start)
      (acl-wait (lambda () (accept-process-output nil 0.5) t) 1)
      (acl-step "initial" (vconcat (mapcar #'vconcat (acl-flymake))))
      (goto-char (point-min))
      (re-search-forward "^capsule \\(act\\)")
      (goto-char (match-beginning 1))
      (acl-step "hover"
        (let ((h (jsonrpc-request (eglot--current-server-or-lose) :textDocument/hover
                                  (eglot--TextDocumentPositionParams) :timeout 20)))
          (let ((c (plist-get h :contents)))
            (if (stringp c) c (or (plist-get c :value) (format "%S" c))))))
      (acl-step "imenu"
        (let ((names nil))
          (dolist (group (funcall imenu-create-index-function))
            (dolist (e (cdr group))
              (push (if (consp e) (car e) e) names)))
          (vconcat names)))
      (goto-char (point-min))
      (re-search-forward "^param \\(dwell\\)")
      (goto-char (match-beginning 1))
      (acl-step "rename" (eglot-rename "wait_time") (buffer-substring-no-properties (point-min) (point-max)))
      ;; an untidy line, then eglot-format-buffer
      (goto-char (point-max))
      (insert "param   messy=1 um\n")
      (acl-sync)
      (acl-step "format" (eglot-format-buffer) (buffer-substring-no-properties (point-min) (point-max)))
      (write-region nil nil (getenv "ACL_EGLOT_FORMATTED"))
      ;; type an error on a known line; flymake reports the server's diagnostic there
      (goto-char (point-min))
      (forward-line (1- (string-to-number (getenv "ACL_EGLOT_BAD_LINE"))))
      (insert (getenv "ACL_EGLOT_BAD") "\n")
      (acl-sync)
      (flymake-start)
      (acl-step "after_error"
        (let ((line (string-to-number (getenv "ACL_EGLOT_BAD_LINE"))))
          (acl-wait (lambda () (flymake-start)
                      (cl-some (lambda (d) (= (car d) line)) (acl-flymake))) 20)
          (vconcat (mapcar #'vconcat (acl-flymake))))))
  (with-temp-file (getenv "ACL_EGLOT_OUT")
    (insert (json-encode acl-out)))
  (ignore-errors (let ((s (eglot-current-server))) (when s (eglot-shutdown s nil 3))))
  (kill-emacs 0))
"""


def _eglot_emacs() -> str:
    emacs = shutil.which("emacs")
    if emacs is None:
        pytest.skip("Emacs is not installed (Debian: apt-get install emacs-nox elpa-eglot)")
    probe = subprocess.run([emacs, "--batch", "--eval", "(require 'eglot)"], capture_output=True,
                           stdin=subprocess.DEVNULL, timeout=60)
    if probe.returncode != 0:
        pytest.skip("eglot is not available in this Emacs (built in from 29; Debian: elpa-eglot)")
    return emacs


def test_eglot_drives_acl_lsp(tmp_path):
    emacs = _eglot_emacs()
    text = DESIGN.read_text(encoding="utf-8")
    lines = text.split("\n")
    design = tmp_path / "cantilever.acl"
    design.write_text(text, encoding="utf-8")
    bad_line = next(i for i, x in enumerate(lines) if x.startswith("observe delta")) + 1   # 1-based
    (tmp_path / "drive.el").write_text(DRIVE, encoding="utf-8")
    out = tmp_path / "out.json"
    formatted = tmp_path / "formatted.acl"
    bin_dir = tmp_path / "bin"                 # `acl` on PATH: this checkout's, with this Python
    bin_dir.mkdir()
    (bin_dir / "acl").write_text(f"#!/bin/sh\nexec {sys.executable} -m acl \"$@\"\n")
    (bin_dir / "acl").chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", HOME=str(tmp_path),
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               ACL_EGLOT_DESIGN=str(design), ACL_EGLOT_OUT=str(out), ACL_EGLOT_FORMATTED=str(formatted),
               ACL_EGLOT_BAD=BAD, ACL_EGLOT_BAD_LINE=str(bad_line))
    run = subprocess.run([emacs, "--batch", "-l", str(ROOT / "editors" / "emacs" / "acl-mode.el"),
                          "-l", str(tmp_path / "drive.el")], cwd=tmp_path, env=env, capture_output=True,
                         stdin=subprocess.DEVNULL, timeout=120)
    assert out.exists(), run.stderr.decode(errors="replace")[:1500]
    got = dict(json.loads(out.read_text(encoding="utf-8")))
    assert got.get("connect") is True, got.get("connect")
    for name, value in got.items():
        assert not (isinstance(value, dict) and "error" in value), (name, value)
    assert got["mode"] == "acl-mode"
    assert got["contact"] == ["acl", "lsp"]            # the program acl-mode.el registers
    assert got["connected"] is True
    assert got["initial"] == [], got["initial"]         # the example is clean (its one warning is ignored)
    hover = got["hover"]
    mode1 = re.search(r"\|\s*1\s*\|\s*([0-9.]+)\s*\|", hover)     # the modes table: | 1 | f (kHz) | ...
    assert "predicted modes" in hover and "f (kHz)" in hover and mode1, hover
    assert 110 <= float(mode1.group(1)) <= 135, hover  # the example's own `require resonance(act) in 110 kHz .. 135 kHz`
    assert {"act", "arm", "dwell", "ramp"} <= set(got["imenu"]), got["imenu"]
    renamed = got["rename"]
    assert renamed.count("wait_time") == text.count("dwell") > 1 and "dwell" not in renamed
    assert "param messy = 1 um" in got["format"], got["format"][-400:]
    assert "param   messy" not in got["format"]
    check = subprocess.run([sys.executable, "-m", "acl", "check", str(formatted)], capture_output=True,
                           text=True, env=env, timeout=120)
    assert check.returncode == 0, check.stdout + check.stderr
    lines_with_error = {line for line, _ in got["after_error"]}
    assert bad_line in lines_with_error, got["after_error"]
    assert any("nosuch_name" in msg for line, msg in got["after_error"] if line == bad_line), got["after_error"]
