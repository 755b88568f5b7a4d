/* Site script (a file, not inline: the Content-Security-Policy allows only own files). */
// Show <time data-local> in the reader's own time zone (the server renders its own zone).
function ptLocalTimes(root) {
  const fmt = new Intl.DateTimeFormat(undefined, {year: "numeric", month: "short", day: "numeric",
    hour: "2-digit", minute: "2-digit", timeZoneName: "short"});
  root.querySelectorAll("time[data-local]").forEach(function (el) {
    const d = new Date(el.getAttribute("datetime"));
    if (!isNaN(d)) { el.title = el.textContent; el.textContent = fmt.format(d); }
  });
}
document.addEventListener("DOMContentLoaded", function () { ptLocalTimes(document); });
document.addEventListener("htmx:afterSwap", function (e) { ptLocalTimes(e.target); });
