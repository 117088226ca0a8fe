// The slider panel's front-end part (hwlib/machinery/panel_controls.py: PanelControls), loaded by anywidget.
const modelId = (ref) => String(ref).replace(/^IPY_MODEL_/, "");
// A change whose origin is the kernel arrives through the model's set_state, which holds
// _state_lock while it sets the values; a change made in the browser does not.
const fromKernel = (model) => model._state_lock !== null && model._state_lock !== undefined;

function button(label, tooltip) {
  const element = document.createElement("button");
  element.className = "jupyter-widgets jupyter-button widget-button";
  element.textContent = label;
  element.title = tooltip;
  return element;
}

async function render({ model, el }) {
  const manager = model.widget_manager;
  const controls = await Promise.all(model.get("controls").map((ref) => manager.get_model(modelId(ref))));
  const params = controls.slice(0, 4), seed = controls[4], step = controls[5], play = controls[6];
  // The panel's state as the browser has it: what the student did last is what it holds.
  const local = { params: params.map((m) => m.get("value")), seed: seed.get("value"), step: null };
  let seq = model.get("drawn");
  let applying = false;
  const send = () => {
    seq += 1;
    el.dataset.sent = String(seq);
    model.set("state", { seq, params: [...local.params], seed: local.seed, step: local.step });
    model.save_changes();
  };
  const listeners = [];
  const listen = (control, handler) => {
    control.on("change:value", handler);
    listeners.push([control, handler]);
  };
  params.forEach((control, index) => listen(control, () => {
    local.params[index] = control.get("value");
    if (applying) return;
    local.step = null;  // a new episode is shown at its end
    if (!fromKernel(control)) send();
  }));
  listen(seed, () => {
    local.seed = seed.get("value");
    local.step = null;
    if (!fromKernel(seed)) send();
  });
  listen(step, () => {
    if (fromKernel(step)) return;  // the kernel showing a new episode's end, or an echo
    local.step = step.get("value");
    if (play.get("playing") && overlay.draw(local)) return;  // ▶ plays in the browser: no frame from the kernel
    send();
  });
  const onPlaying = () => {
    if (!play.get("playing") && overlay.shown) {
      overlay.until = seq + 1;  // the kernel's own frame of the step where the play stopped replaces the overlay
      send();
    }
  };
  play.on("change:playing", onPlaying);

  const presets = document.createElement("div");
  presets.className = "hwlib-presets";
  for (const preset of model.get("presets")) {
    const element = button(preset.name, preset.tooltip);
    element.addEventListener("click", () => {
      applying = true;
      try {
        params.forEach((control, index) => {
          control.set("value", preset.params[index]);
          control.save_changes();
        });
      } finally {
        applying = false;
      }
      local.params = [...preset.params];
      local.step = null;
      send();
    });
    presets.append(element);
  }
  const landscape = button("", "");
  const icon = document.createElement("i");
  icon.className = "fa fa-crosshairs";
  landscape.append(icon, " " + model.get("landscape_label"));
  landscape.addEventListener("click", () => model.send({ event: "send_params", params: [...local.params] }));
  const showLandscape = () => {
    landscape.disabled = !model.get("landscape_enabled");
    landscape.title = model.get("landscape_tooltip");
  };
  showLandscape();
  const overlay = playOverlay(model, el);
  const showDrawn = () => {
    el.dataset.drawn = String(model.get("drawn"));
    if (overlay.until !== null && model.get("drawn") >= overlay.until) overlay.hide();
  };
  showDrawn();
  model.on("change:landscape_enabled", showLandscape);
  model.on("change:landscape_tooltip", showLandscape);
  model.on("change:drawn", showDrawn);
  el.classList.add("hwlib-panel-controls");
  el.append(presets, landscape);
  model.send({ event: "connected" });
  const stopNaming = nameControls(model, el);
  return () => {
    for (const [control, handler] of listeners) control.off("change:value", handler);
    play.off("change:playing", onPlaying);
    overlay.hide();
    stopNaming();
  };
}

// ipywidgets leaves the sliders' handles, ▶ Play's buttons and the picture without a name a screen reader
// can say, and a handle reads its raw value (-0.30000000000000004). Name them, with values as the readouts
// show them, make the status line a live region, and do it again whenever the panel's page changes.
function nameControls(model, el) {
  let observer = null, tries = 0;
  const set = (element, name, value) => {
    if (value !== undefined && value !== null && element.getAttribute(name) !== value) element.setAttribute(name, value);
  };
  const name = (root) => {
    for (const slider of root.querySelectorAll(".widget-hslider")) {
      const handle = slider.querySelector(".noUi-handle");
      const readout = slider.querySelector(".widget-readout")?.textContent.trim();
      if (!handle) continue;
      set(handle, "aria-label", slider.querySelector(".widget-label")?.textContent.trim());
      if (readout) {
        set(handle, "aria-valuetext", readout);
        const value = Number(readout.replace("\u2212", "-"));
        if (Number.isFinite(value)) set(handle, "aria-valuenow", String(value));
      }
    }
    const names = model.get("button_names");
    for (const button of root.querySelectorAll(".widget-play button")) {
      const icon = Object.keys(names).find((icon) => button.querySelector(`.${icon}`));
      if (icon) set(button, "aria-label", names[icon]);
    }
    const image = root.querySelector("img.hwlib-episode");
    if (image) set(image, "alt", model.get("image_alt"));
    for (const status of root.querySelectorAll(".hwlib-status")) {
      set(status, "role", "status");
      set(status, "aria-live", "polite");
      set(status, "aria-atomic", "true");
    }
  };
  const attach = () => {
    const root = el.closest(".hwlib-slider-panel");
    if (!root) {
      if (++tries < 600) timer = setTimeout(attach, 50);  // the panel's box is not on the page yet
      return;
    }
    name(root);
    observer = new MutationObserver(() => name(root));
    observer.observe(root, { subtree: true, childList: true, characterData: true, attributes: true,
                             attributeFilter: ["aria-valuetext", "aria-valuenow", "src", "class"] });
    model.on("change:image_alt", onAlt);
  };
  const onAlt = () => {
    const image = el.closest(".hwlib-slider-panel")?.querySelector("img.hwlib-episode");
    if (image) set(image, "alt", model.get("image_alt"));
  };
  let timer = setTimeout(attach, 0);
  return () => {
    clearTimeout(timer);
    observer?.disconnect();
    model.off("change:image_alt", onAlt);
  };
}

// While ▶ plays, the browser draws the time cursors and the cart over the episode's picture
// without them (both from the kernel, once per episode): the kernel draws no frame per step, so
// the play keeps its pace whatever the kernel is doing. When it stops, the kernel's frame returns.
function playOverlay(model, el) {
  const state = { shown: false, until: null, canvas: null, image: null, bitmap: null, data: null };
  const load = async () => {
    const data = model.get("overlay");
    state.data = null;
    state.bitmap = null;
    const png = model.get("overlay_png");
    if (!data || !png || !png.byteLength) return;
    state.bitmap = await createImageBitmap(new Blob([png], { type: "image/png" }));
    state.data = data;
  };
  model.on("change:overlay_png", load);
  load();
  const place = () => {
    const panel = el.closest(".hwlib-slider-panel");
    const image = panel && panel.querySelector("img.hwlib-episode");
    if (!image) return false;
    if (!state.canvas || state.image !== image) {
      state.canvas?.remove();
      state.canvas = document.createElement("canvas");
      state.canvas.className = "hwlib-play-overlay";
      image.insertAdjacentElement("afterend", state.canvas);
      state.image = image;
    }
    const canvas = state.canvas;
    canvas.width = image.naturalWidth || image.width;
    canvas.height = image.naturalHeight || image.height;
    canvas.style.left = image.offsetLeft + "px";
    canvas.style.top = image.offsetTop + "px";
    return true;
  };
  state.draw = (local) => {
    const data = state.data;
    if (!data || !state.bitmap || data.seed !== local.seed || data.params.some((value, i) => value !== local.params[i])) return false;
    if (local.step === null || local.step > data.num_steps || !place()) return false;
    const k = local.step, ctx = state.canvas.getContext("2d");
    ctx.drawImage(state.bitmap, 0, 0);
    ctx.strokeStyle = data.cursor.color;
    ctx.lineWidth = data.cursor.width;
    for (const cursor of data.cursors) {
      ctx.beginPath();
      ctx.moveTo(cursor.x[k], cursor.top);
      ctx.lineTo(cursor.x[k], cursor.bottom);
      ctx.stroke();
    }
    ctx.save();
    ctx.beginPath();
    ctx.rect(data.clip.left, data.clip.top, data.clip.width, data.clip.height);
    ctx.clip();
    ctx.fillStyle = data.cart.color;
    ctx.fillRect(data.cart.left[k], data.cart.top, data.cart.width, data.cart.height);
    ctx.strokeStyle = data.pole.color;
    ctx.lineWidth = data.pole.width;
    ctx.lineCap = "round";
    ctx.beginPath();
    ctx.moveTo(data.pole.x0[k], data.pole.y0);
    ctx.lineTo(data.pole.x1[k], data.pole.y1[k]);
    ctx.stroke();
    ctx.fillStyle = data.axle.color;
    ctx.beginPath();
    ctx.arc(data.pole.x0[k], data.pole.y0, data.axle.radius, 0, 2 * Math.PI);
    ctx.fill();
    ctx.restore();
    ctx.fillStyle = data.caption.color;
    ctx.font = `${data.caption.size}px "DejaVu Sans", sans-serif`;
    ctx.textAlign = "center";
    ctx.fillText(`step ${k} of ${data.num_steps}` + (k === data.num_steps ? `: ${data.ending}` : ""), data.caption.x, data.caption.y);
    state.canvas.style.display = "block";
    state.shown = true;
    state.until = null;
    el.dataset.frames = String(Number(el.dataset.frames || 0) + 1);
    return true;
  };
  state.hide = () => {
    if (state.canvas) state.canvas.style.display = "none";
    state.shown = false;
    state.until = null;
  };
  return state;
}

export default { render };
