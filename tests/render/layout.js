// Layout checks of a rendered page, run by the browser after the page has loaded: every
// figure's text inside its figure, no two labels on top of each other, no text too small
// to read, nothing wider than the window. The findings go into a `pre` element (id
// dynid-layout) as JSON for the test to read from the dumped DOM.
(function () {
  const out = {
    window_width: window.innerWidth,
    page_width: document.documentElement.scrollWidth,
    figures: 0,
    labels: 0,
    min_label_px: null,
    outside: [],
    overlapping: [],
    too_small: [],
    too_wide: [],
  };
  const name = (t) => JSON.stringify(t.textContent.trim().slice(0, 60));
  const svgs = Array.from(document.querySelectorAll("svg"));
  out.figures = svgs.length;
  svgs.forEach((svg, i) => {
    const f = svg.getBoundingClientRect();
    const boxes = Array.from(svg.querySelectorAll("text"))
      .filter((t) => t.textContent.trim().length > 0)
      .map((t) => [t, t.getBoundingClientRect()]);
    out.labels += boxes.length;
    for (const [t, b] of boxes) {
      if (b.left < f.left - 1 || b.right > f.right + 1 || b.top < f.top - 1 || b.bottom > f.bottom + 1) {
        out.outside.push(`figure ${i + 1}: ${name(t)}`);
      }
      if (out.min_label_px === null || b.height < out.min_label_px) out.min_label_px = b.height;
      if (b.height < 10) out.too_small.push(`figure ${i + 1}: ${name(t)} ${b.height.toFixed(1)} px`);
    }
    for (let a = 0; a < boxes.length; a++) {
      for (let c = a + 1; c < boxes.length; c++) {
        const [ta, ba] = boxes[a];
        const [tc, bc] = boxes[c];
        const w = Math.min(ba.right, bc.right) - Math.max(ba.left, bc.left);
        const h = Math.min(ba.bottom, bc.bottom) - Math.max(ba.top, bc.top);
        const smaller = Math.min(ba.width * ba.height, bc.width * bc.height);
        if (w > 0 && h > 0 && w * h > 0.2 * smaller) {
          out.overlapping.push(`figure ${i + 1}: ${name(ta)} over ${name(tc)}`);
        }
      }
    }
  });
  for (const el of document.querySelectorAll("body *")) {
    if (el.closest("svg") || el.id === "dynid-layout") continue;
    const b = el.getBoundingClientRect();
    if (b.width > 0 && b.right > window.innerWidth + 1) {
      out.too_wide.push(`<${el.tagName.toLowerCase()}> ${name(el)} ends at ${b.right.toFixed(0)} px`);
    }
  }
  const pre = document.createElement("pre");
  pre.id = "dynid-layout";
  pre.textContent = JSON.stringify(out);
  document.body.appendChild(pre);
})();
