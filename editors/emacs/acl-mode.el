;;; acl-mode.el --- Major mode for acl design files, with eglot -*- lexical-binding: t -*-

;; Load it from init.el:  (load "/path/to/acl/editors/emacs/acl-mode.el")
;; Needs `acl' on PATH (pip install '.[lsp]' in a clone of acl).  eglot is built into Emacs 29+; on Emacs 26-28
;; install it from GNU ELPA (M-x package-install RET eglot) or Debian's elpa-eglot.
;; Then M-x eglot in an .acl buffer, or (add-hook 'acl-mode-hook #'eglot-ensure).
;; tests/test_lsp_eglot.py loads this file in `emacs --batch' and drives `acl lsp' through eglot.

;;; Code:

(defgroup acl nil "Editing acl design files." :group 'languages)

(defconst acl-mode--keywords
  '("param" "uncertainty" "use" "mount" "fix" "link" "observe" "require" "program" "on" "to"
    "with" "for" "in" "at" "along" "above" "phase" "free" "like" "limit" "slew" "margin" "using"
    "log" "import" "extends" "as")
  "Keywords of acl (the TextMate grammar's keyword.other and keyword.control.import).")

(defconst acl-mode--steps
  '("drive" "sweep" "pause" "follow" "switch" "hold" "cross")
  "Program steps of acl.")

(defconst acl-mode--kinds
  '("medium" "material" "transducer" "generator" "amplifier" "capsule" "beam" "spring" "truss"
    "latch" "anchor" "effect" "cavity" "orifice")
  "Declaration kinds of acl.")

(defconst acl-mode--font-lock
  `((,(regexp-opt acl-mode--steps 'symbols) . font-lock-builtin-face)
    (,(concat (regexp-opt (append acl-mode--kinds '("program" "param" "observe" "use")) 'symbols)
              "[ \t]+\\([A-Za-z_][A-Za-z0-9_]*\\)")
     (1 font-lock-keyword-face) (2 font-lock-function-name-face))
    (,(regexp-opt acl-mode--kinds 'symbols) . font-lock-type-face)
    (,(regexp-opt acl-mode--keywords 'symbols) . font-lock-keyword-face)
    ;; a number and its unit: 125 kHz, 10 um, 6.51e4 um^3
    ("\\_<[0-9]+\\(?:\\.[0-9]*\\)?\\(?:[eE][-+]?[0-9]+\\)?[ \t]*\\([A-Za-zµμ°Ω%][A-Za-z0-9µμ°Ω%]*\\(?:\\^-?[0-9]+\\)?\\)?"
     (1 font-lock-constant-face nil t)))
  "Font-lock rules of `acl-mode'.")

(defvar acl-mode-syntax-table
  (let ((table (make-syntax-table)))
    (modify-syntax-entry ?# "<" table)
    (modify-syntax-entry ?\n ">" table)
    (modify-syntax-entry ?_ "_" table)
    (modify-syntax-entry ?\" "\"" table)
    table)
  "Syntax table of `acl-mode': `#' starts a comment to the end of the line.")

;;;###autoload
(define-derived-mode acl-mode prog-mode "acl"
  "Major mode for acl design files (.acl)."
  :syntax-table acl-mode-syntax-table
  (setq-local comment-start "# ")
  (setq-local comment-start-skip "#+[ \t]*")
  (setq-local indent-tabs-mode nil)
  (setq-local tab-width 2)
  (setq-local font-lock-defaults '(acl-mode--font-lock)))

;;;###autoload
(add-to-list 'auto-mode-alist '("\\.acl\\'" . acl-mode))

(with-eval-after-load 'eglot
  (add-to-list 'eglot-server-programs '(acl-mode . ("acl" "lsp"))))

(provide 'acl-mode)
;;; acl-mode.el ends here
