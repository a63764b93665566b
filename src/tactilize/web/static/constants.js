// The numbers of the server's rules this page needs (tactilize/web/constants.py:
// the calibration card, the default CSS pixel, the repeat limit, the batch limits,
// the audio's wavelet rule), loaded once for every module of either page, so no
// number is copied between Python and JavaScript.  The URL is relative to this
// module: the pen page serves it at /static/, the experiment at /experiment/static/,
// each beside its own api/constants.

const response = await fetch(new URL("../api/constants", import.meta.url));
if (!response.ok) throw new Error(`constants: the server answered ${response.status}`);

/** The server's constants (GET api/constants). */
export const constants = await response.json();
