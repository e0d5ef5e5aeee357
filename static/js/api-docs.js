// The API's documentation page, /docs (app.web.routes.api_docs; only with `sp serve
// --api-docs`): starts the vendored Swagger UI on the station's /openapi.json.  A file of its
// own rather than the inline script FastAPI's page has, so the page's policy allows no
// inline script at all.
(() => {
  "use strict";

  window.ui = window.SwaggerUIBundle({
    url: "/openapi.json",
    dom_id: "#swagger-ui",
    layout: "BaseLayout",
    // no deep links: with them each operation's path is a link inside the button that opens
    // it (a control in a control, which keyboards and screen readers cannot tell apart)
    deepLinking: false,
    showExtensions: true,
    showCommonExtensions: true,
    validatorUrl: null, // no badge fetched from swagger.io: the page loads only its own files
    presets: [window.SwaggerUIBundle.presets.apis],
  });
})();
