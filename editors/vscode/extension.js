// acl for VS Code: the grammar (syntaxes/acl.tmLanguage.json) colours files on its own; this
// script starts the acl language server (`acl lsp`, over stdio) for diagnostics, hover,
// go to definition, completion and formatting. The command is the setting `acl.server.command`.
"use strict";

const vscode = require("vscode");
const { LanguageClient, TransportKind } = require("vscode-languageclient/node");

let client;

function activate(context) {
  const config = vscode.workspace.getConfiguration("acl");
  if (!config.get("server.enabled", true)) {
    return;
  }
  const [command, ...args] = config.get("server.command", ["acl", "lsp"]);
  const serverOptions = { command, args, transport: TransportKind.stdio };
  const clientOptions = {
    documentSelector: [
      { scheme: "file", language: "acl" },
      { scheme: "untitled", language: "acl" },
    ],
  };
  client = new LanguageClient("acl", "acl language server", serverOptions, clientOptions);
  client.start().catch((err) => {
    vscode.window.showWarningMessage(
      `acl: could not start the language server (${command} ${args.join(" ")}): ${err.message}. ` +
        "Install it with `pip install '.[lsp]'` in a clone of acl, or set acl.server.command."
    );
  });
  context.subscriptions.push({ dispose: () => client && client.stop() });
}

function deactivate() {
  return client ? client.stop() : undefined;
}

module.exports = { activate, deactivate };
