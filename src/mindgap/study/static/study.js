// The only script of the study pages: show the slider's value, hold the submit button
// until the slider was moved (it has no value, and no name, before that: an untouched
// slider sends nothing and the server refuses the answer) and the study's minimum time
// per item is over, and stop a second click from sending the form twice (the server
// records one answer either way).
document.addEventListener("DOMContentLoaded", function () {
  var form = document.querySelector("form.answer");
  if (!form) return;
  var button = form.querySelector("button[type=submit]");
  var slider = document.getElementById("rating");
  var out = document.getElementById("rating-value");
  var moved = !slider || slider.name === "rating";
  var waited = !(parseFloat(form.dataset.wait || "0") > 0);
  function update() { button.disabled = !(moved && waited); }
  function touch() {
    if (!moved) {
      moved = true;
      slider.name = "rating";
      slider.parentNode.classList.remove("untouched");
      var hint = document.getElementById("move-hint");
      if (hint) hint.hidden = true;
    }
    out.textContent = slider.value;
    update();
  }
  if (slider) {
    slider.addEventListener("input", touch);
    slider.addEventListener("change", touch);
    // a click or a key on the thumb where it already is also counts as a choice of that value
    slider.addEventListener("pointerup", touch);
    slider.addEventListener("keyup", function (e) {
      if (/^(Arrow|Home$|End$|Page)/.test(e.key)) touch();
    });
  }
  if (!waited) {
    setTimeout(function () { waited = true; update(); }, parseFloat(form.dataset.wait) * 1000);
  }
  update();
  form.addEventListener("submit", function () {
    setTimeout(function () { button.disabled = true; }, 0);
  });
});
