/* "Copy" button of the new API key page. */
document.getElementById("copy-key").addEventListener("click", function () {
  const field = document.getElementById("api-key");
  const status = document.getElementById("copy-status");
  field.select();
  const done = function () { status.textContent = "Copied to the clipboard."; };
  if (navigator.clipboard && window.isSecureContext) {
    navigator.clipboard.writeText(field.value).then(done, function () { document.execCommand("copy"); done(); });
  } else { document.execCommand("copy"); done(); }
});
