// The only script of the study pages: show the slider's value, hold the submit button for
// the study's minimum time per item, and stop a second click from sending the form twice
// (the server records one answer either way).
document.addEventListener("DOMContentLoaded", function () {
  var slider = document.getElementById("rating");
  var out = document.getElementById("rating-value");
  if (slider && out) {
    slider.addEventListener("input", function () { out.textContent = slider.value; });
  }
  var form = document.querySelector("form.answer");
  if (!form) return;
  var button = form.querySelector("button[type=submit]");
  var wait = parseFloat(form.dataset.wait || "0");
  if (wait > 0) {
    button.disabled = true;
    setTimeout(function () { button.disabled = false; }, wait * 1000);
  }
  form.addEventListener("submit", function () {
    setTimeout(function () { button.disabled = true; }, 0);
  });
});
