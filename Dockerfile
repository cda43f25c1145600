# The cpkb image: the service (`cpkb serve`), migrations (`cpkb db upgrade`) and planner workers
# (`cpkb plan`, `cpkb bench`) all run from it; docker-compose.yml wires them together.
#
# Two stages: the compiler needed by packages that build from source stays in the first; the
# final image holds only the virtual environment.
ARG PYTHON_IMAGE=python:3.11-slim

FROM ${PYTHON_IMAGE} AS build
RUN apt-get update \
    && apt-get install -y --no-install-recommends build-essential \
    && rm -rf /var/lib/apt/lists/*
ENV PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1
RUN python -m venv /opt/cpkb
ENV PATH=/opt/cpkb/bin:$PATH
# The CPU build of torch from its own index, first and alone: PyPI's torch is the CUDA build
# (several GB). Point TORCH_INDEX_URL at a mirror, or TORCH_SPEC at another release, as needed.
ARG TORCH_INDEX_URL=https://download.pytorch.org/whl/cpu
ARG TORCH_SPEC=torch==2.13.0
RUN pip install --index-url "${TORCH_INDEX_URL}" "${TORCH_SPEC}"
WORKDIR /src
COPY deploy/requirements.lock ./deploy/requirements.lock
RUN pip install -r deploy/requirements.lock
COPY pyproject.toml README.md LICENSE ./
COPY cpkb ./cpkb
COPY server ./server
COPY client ./client
COPY contract ./contract
COPY planner ./planner
COPY surrogate ./surrogate
COPY migrations ./migrations
RUN pip install --no-deps .

FROM ${PYTHON_IMAGE}
ENV PYTHONUNBUFFERED=1 \
    PATH=/opt/cpkb/bin:$PATH
# Graphviz's dot lays out the dashboard's causal graphs (without it they get a plainer layout).
RUN apt-get update \
    && apt-get install -y --no-install-recommends graphviz \
    && rm -rf /var/lib/apt/lists/*
COPY --from=build /opt/cpkb /opt/cpkb
WORKDIR /app
COPY deploy ./deploy
RUN useradd --create-home --uid 10001 cpkb && mkdir -p /runs && chown cpkb /runs
USER cpkb
EXPOSE 8000
CMD ["cpkb", "serve", "--host", "0.0.0.0", "--port", "8000"]
