/*
 * The book's search scores (conf.py html_search_scorer; Sphinx's searchtools.js reads this
 * Scorer in place of its own). Sphinx's defaults with one change: a chapter (a notebook's page)
 * scores CHAPTER more, so that a concept ("Jacobian", "replay") finds the chapter that teaches
 * it before the API entries whose names contain the word (tests/integration/test_book_offline.py
 * searches the built book).
 */
var CHAPTER = 30;
var Scorer = {
  score: (result) => {
    const [docname, title, anchor, descr, score, filename, kind] = result;
    return docname.startsWith("notebooks/") ? score + CHAPTER : score;
  },
  objNameMatch: 11,
  objPartialMatch: 6,
  objPrio: {
    0: 15,
    1: 5,
    2: -5,
  },
  objPrioDefault: 0,
  title: 15,
  partialTitle: 7,
  term: 5,
  partialTerm: 2,
};
