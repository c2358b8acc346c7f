// MathJax 3 for pymdownx.arithmatex in generic mode: typeset only what arithmatex marked,
// from the copy of MathJax shipped with these pages (assets/mathjax, no network needed);
// its fonts are found beside it, in assets/mathjax/output/chtml/fonts/woff-v2.
window.MathJax = {
  tex: {
    inlineMath: [["\\(", "\\)"]],
    displayMath: [["\\[", "\\]"]],
    processEscapes: true,
    processEnvironments: true,
  },
  options: {
    ignoreHtmlClass: ".*|",
    processHtmlClass: "arithmatex",
  },
};

// Material's document$ emits for each page shown (also when instant navigation swaps pages):
// typeset what arithmatex marked there once MathJax has started. The output's cache is kept:
// clearing it would drop the styles of maths that is already typeset.
if (typeof document$ !== "undefined") {
  document$.subscribe(() => {
    const startup = window.MathJax && window.MathJax.startup;
    if (!startup || !startup.promise) {
      return; // MathJax not loaded yet: it typesets the page when it starts
    }
    startup.promise.then(() => {
      MathJax.typesetClear();
      MathJax.texReset();
      return MathJax.typesetPromise();
    });
  });
}
